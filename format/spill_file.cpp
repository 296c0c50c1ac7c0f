#include "format/spill_file.hpp"

#include "format/error.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <unistd.h>

namespace facemorph::format {

SpillFile::SpillFile(std::string what) : what_(std::move(what)) {}

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

void SpillFile::open() {
  // Unlinked as soon as it is open: the file goes when the process ends, however it ends.
  std::error_code error;
  const std::filesystem::path folder = std::filesystem::temp_directory_path(error);
  if (error) {
    const char* named = std::getenv("TMPDIR");
    throw Error(ErrorCode::kIo, "cannot create a temporary file for " + what_ + ": no temporary folder (TMPDIR" +
                                    (named ? " = " + std::string(named) : std::string(" unset")) + "): " + error.message());
  }
  std::string name = (folder / "facemorph-spill-XXXXXX").string();
  fd_ = ::mkstemp(name.data());
  if (fd_ < 0) {
    throw Error(ErrorCode::kIo, "cannot create a temporary file for " + what_ + " in " + folder.string() + ": " + std::strerror(errno) +
                                    " (TMPDIR names another folder)");
  }
  ::unlink(name.c_str());
}

SpillFile::Record SpillFile::append(const char* data, size_t size) {
  Record record;
  {
    std::lock_guard lock(mutex_);
    if (fd_ < 0) open();
    record.offset = end_;
    end_ += size;
  }
  record.size = size;
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::pwrite(fd_, data + done, size - done, static_cast<off_t>(record.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      throw Error(ErrorCode::kIo, "cannot write " + what_ + " to the temporary file in " + std::filesystem::temp_directory_path().string() +
                                      ": " + std::strerror(errno) + " (a full disk? TMPDIR names another folder)");
    }
    done += static_cast<size_t>(n);
  }
  return record;
}

std::vector<char> SpillFile::read(const Record& record) const {
  std::vector<char> bytes(record.size);
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(record.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw Error(ErrorCode::kIo,
                  "cannot read " + what_ + " back from the temporary file: " + (n < 0 ? std::strerror(errno) : "the file is short"));
    done += static_cast<size_t>(n);
  }
  return bytes;
}

void SpillFile::clear() {
  std::lock_guard lock(mutex_);
  if (fd_ >= 0 && ::ftruncate(fd_, 0) != 0)
    throw Error(ErrorCode::kIo, "cannot empty the temporary file of " + what_ + ": " + std::strerror(errno));
  end_ = 0;
}

uint64_t SpillFile::size() const {
  std::lock_guard lock(mutex_);
  return end_;
}

}  // namespace facemorph::format
