// Whole-file reads with a size bound, and writes that never leave a half file behind: data goes to
// a temporary name in the destination folder and is renamed over the destination only when complete.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <span>
#include <string_view>
#include <vector>

namespace facemorph::format {

// Reads the whole file. Throws kIo naming the file if it cannot be opened or read, and
// kInvalidArgument if it is larger than `max_bytes`.
std::vector<uint8_t> read_file(const std::filesystem::path& path, uint64_t max_bytes = uint64_t{1} << 34);

// A file's bytes mapped read-only (POSIX mmap): pages are read as they are touched and belong to
// the page cache, not the process's heap, so opening a long file costs what is read of it. The file
// must not be truncated in place while mapped (touching a page past its new end raises SIGBUS);
// facemorph's writers replace files by rename, which leaves a mapping intact.
class MappedFile {
 public:
  // Throws kIo naming the file if it cannot be opened or mapped.
  explicit MappedFile(const std::filesystem::path& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  std::span<const uint8_t> bytes() const { return {data_, size_}; }
  // Tells the system the pages read so far are not needed soon (madvise MADV_DONTNEED): they leave
  // the process's resident set and are read again from the file when next touched.
  void release_pages() const;
  // The same for the pages wholly inside bytes [offset, offset + size): a reader done with one part
  // of a long file (a part file's record) keeps its resident set to what it reads next.
  void release_pages(uint64_t offset, uint64_t size) const;

 private:
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
};

// Writes `data` to `path` atomically (temporary file + rename). Throws kIo naming the file.
void write_file_atomically(const std::filesystem::path& path, std::span<const uint8_t> data);
void write_file_atomically(const std::filesystem::path& path, std::string_view text);
// The same for a file written by `write` to the stream it is given (a stream error is kIo); a throw
// from `write` removes the temporary file and passes on.
void write_file_atomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write);

// A temporary sibling name for `path` (same folder, so rename is atomic), unique per process+call.
std::filesystem::path temporary_sibling(const std::filesystem::path& path);

// Renames `from` over `to`; on failure removes `from` and throws kIo naming `to`.
void commit_temporary(const std::filesystem::path& from, const std::filesystem::path& to);

}  // namespace facemorph::format
