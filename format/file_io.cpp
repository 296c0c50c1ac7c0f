#include "format/file_io.hpp"

#include "format/error.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <system_error>

namespace facemorph::format {
namespace fs = std::filesystem;

std::vector<uint8_t> read_file(const fs::path& path, uint64_t max_bytes) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw Error(ErrorCode::kIo, path.string() + ": is a directory, not a file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw Error(ErrorCode::kIo, path.string() + ": cannot open: " + std::strerror(errno));
  }
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw Error(ErrorCode::kIo, path.string() + ": cannot determine the file size");
  if (static_cast<uint64_t>(size) > max_bytes) {
    throw Error(ErrorCode::kInvalidArgument,
                path.string() + ": " + std::to_string(size) + " bytes exceeds the limit of " + std::to_string(max_bytes));
  }
  in.seekg(0, std::ios::beg);
  std::vector<uint8_t> data(static_cast<size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(data.data()), size)) {
    throw Error(ErrorCode::kIo, path.string() + ": read failed");
  }
  return data;
}

MappedFile::MappedFile(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw Error(ErrorCode::kIo, path.string() + ": is a directory, not a file");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(ErrorCode::kIo, path.string() + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size < 0) {
    const int error = errno;
    ::close(fd);
    throw Error(ErrorCode::kIo, path.string() + ": cannot determine the file size: " + std::strerror(error));
  }
  size_ = static_cast<size_t>(st.st_size);
  if (size_ > 0) {
    void* mapped = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (mapped == MAP_FAILED) {
      const int error = errno;
      ::close(fd);
      throw Error(ErrorCode::kIo, path.string() + ": cannot map: " + std::strerror(error));
    }
    data_ = static_cast<const uint8_t*>(mapped);
  }
  ::close(fd);  // the mapping keeps the file
}

void MappedFile::release_pages() const {
  if (data_) ::madvise(const_cast<uint8_t*>(data_), size_, MADV_DONTNEED);  // advice: a failure changes nothing read
}

void MappedFile::release_pages(uint64_t offset, uint64_t size) const {
  const auto page = static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
  const uint64_t end = std::min<uint64_t>(offset + size, size_);
  const uint64_t first = (offset + page - 1) / page * page, last = end / page * page;
  if (data_ && first < last) ::madvise(const_cast<uint8_t*>(data_) + first, last - first, MADV_DONTNEED);
}

MappedFile::~MappedFile() {
  if (data_) ::munmap(const_cast<uint8_t*>(data_), size_);
}

fs::path temporary_sibling(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  fs::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  return tmp;
}

void commit_temporary(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  if (ec) {
    const std::string why = ec.message();  // the rename's, before the clean-up's status replaces it
    fs::remove(from, ec);
    throw Error(ErrorCode::kIo, to.string() + ": cannot replace the file: " + why);
  }
}

void write_file_atomically(const fs::path& path, std::span<const uint8_t> data) {
  write_file_atomically(
      path, [&](std::ostream& out) { out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size())); });
}

void write_file_atomically(const fs::path& path, const std::function<void(std::ostream&)>& write) {
  const fs::path tmp = temporary_sibling(path);
  const auto remove_temporary = [&] {
    std::error_code ec;
    fs::remove(tmp, ec);
  };
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw Error(ErrorCode::kIo, path.string() + ": cannot create: " + std::strerror(errno));
    }
    try {
      write(out);
    } catch (...) {
      out.close();
      remove_temporary();
      throw;
    }
    out.flush();
    if (!out) {
      out.close();
      remove_temporary();
      throw Error(ErrorCode::kIo, path.string() + ": write failed (disk full?)");
    }
  }
  commit_temporary(tmp, path);
}

void write_file_atomically(const fs::path& path, std::string_view text) {
  write_file_atomically(path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

}  // namespace facemorph::format
