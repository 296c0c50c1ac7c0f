// The tools' decoder limits (--max-memory, --max-grid, ... : tool_support.hpp) as the player API's
// options: what fmdec, fmplay and fminfo open their file with through facemorph.h; and a failed
// call's message as those tools print it.
#pragma once

#include "facemorph.h"

#include "codec/core/limits/decoder_limits.hpp"
#include "format/error.hpp"

#include <memory>
#include <string>
#include <vector>

namespace facemorph::tools {

// `limits` as fm_decoder_options, every field the API has (its defaults where `limits` has none).
inline fm_decoder_options player_options(const DecoderLimits& limits) {
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  options.max_grid_n = static_cast<uint32_t>(limits.max_grid_n);
  options.max_keyframes = limits.max_keyframes;
  options.max_texture_size = static_cast<uint32_t>(limits.max_texture_size);
  options.max_memory_bytes = limits.max_memory_bytes;
  options.max_work = limits.max_work;
  return options;
}

// The message of the last failed call (fm_last_error_message) without the C function's name it
// starts with ("fm_file_open: face.fmv: ..."), so that a tool's error names the file and the reason
// first, as the tools always have and the web page repeats.
inline std::string player_error_message() {
  std::string message = fm_last_error_message();
  if (const size_t colon = message.find(": "); message.rfind("fm_", 0) == 0 && colon != std::string::npos) message.erase(0, colon + 2);
  return message;
}

// A failed call of the player API as a tool's error: the status is the error's code (facemorph.h
// mirrors ErrorCode), the message names the file first (player_error_message).
inline void check_player(fm_status status) {
  if (status == FM_OK) return;
  throw Error(static_cast<ErrorCode>(status), player_error_message());
}

// A file opened as a player opens it (fm_file_open_with_options), with what fm_file_get_info and
// fm_file_get_keyframe_times say of it: a file no player may open is refused here, before anything
// else reads it.
class PlayerFile {
 public:
  PlayerFile(const std::string& path, const DecoderLimits& limits) {
    const fm_decoder_options options = player_options(limits);
    fm_file* file = nullptr;
    check_player(fm_file_open_with_options(path.c_str(), &options, &file));
    file_.reset(file);
    fm_info_init(&info_);
    check_player(fm_file_get_info(file, &info_));
  }

  fm_file* get() const { return file_.get(); }
  const fm_info& info() const { return info_; }
  std::vector<double> keyframe_times() const {
    size_t count = 0;
    check_player(fm_file_get_keyframe_times(file_.get(), nullptr, 0, &count));
    std::vector<double> times(count);
    check_player(fm_file_get_keyframe_times(file_.get(), times.data(), times.size(), &count));
    return times;
  }

 private:
  std::unique_ptr<fm_file, decltype(&fm_file_close)> file_{nullptr, fm_file_close};
  fm_info info_{};
};

}  // namespace facemorph::tools
