// An unlinked temporary file of byte records: where a writer or the encoder keeps what it has made
// and needs again later, so memory holds the few records being worked on, not all of them.
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

namespace facemorph::format {

class SpillFile {
 public:
  // `what` names the contents in errors ("the frames' maps"). The file is made on the first append.
  explicit SpillFile(std::string what);
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  struct Record {
    uint64_t offset = 0, size = 0;  // bytes
  };
  // Appends `size` bytes and says where they went. Thread-safe: each record gets its own range of
  // the file, so threads write side by side. The file is made in TMPDIR and unlinked at once, so it
  // goes when the process ends, however it ends. Throws kIo when it cannot be made or written (a
  // full disk: TMPDIR names another folder).
  Record append(const char* data, size_t size);
  // A record's bytes, read back. Thread-safe. Throws kIo on a failed or short read.
  std::vector<char> read(const Record& record) const;
  // Empties the file (records handed out before are no longer valid).
  void clear();
  uint64_t size() const;  // bytes written since the last clear

 private:
  void open();

  std::string what_;
  int fd_ = -1;
  mutable std::mutex mutex_;
  uint64_t end_ = 0;
};

}  // namespace facemorph::format
