// What the C API tests share: a file and its decoder opened through facemorph.h alone, closed at
// scope exit.
#pragma once

#include "facemorph.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace facemorph::testing {

struct CApiOpened {
  fm_file* file = nullptr;
  fm_decoder* decoder = nullptr;
  fm_info info;
  fm_status status = FM_OK;

  // The file at `path`: each step is expected to succeed.
  explicit CApiOpened(const std::string& path) {
    fm_info_init(&info);
    status = fm_file_open(path.c_str(), &file);
    EXPECT_EQ(status, FM_OK) << fm_last_error_message();
    if (status == FM_OK) create_decoder();
  }
  // `bytes` in memory, copied or borrowed (API 1.1); `status` says whether the open succeeded.
  CApiOpened(const std::vector<uint8_t>& bytes, bool borrowed) {
    fm_info_init(&info);
    status = borrowed ? fm_file_open_memory_borrowed(bytes.data(), bytes.size(), nullptr, &file)
                      : fm_file_open_memory(bytes.data(), bytes.size(), &file);
    if (status == FM_OK) create_decoder();
  }
  ~CApiOpened() {
    fm_decoder_destroy(decoder);
    fm_file_close(file);
  }
  CApiOpened(const CApiOpened&) = delete;
  CApiOpened& operator=(const CApiOpened&) = delete;

 private:
  void create_decoder() {
    EXPECT_EQ(fm_file_get_info(file, &info), FM_OK);
    EXPECT_EQ(fm_decoder_create(file, &decoder), FM_OK) << fm_last_error_message();
  }
};

}  // namespace facemorph::testing
