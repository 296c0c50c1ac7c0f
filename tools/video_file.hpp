// An MP4 being written by fmdec --preview SEQ.mp4 or fmplay --video: through libfacemorph_video
// (tools/video_plugin.cpp), loaded from beside the executable on first use, so the tools start
// without OpenCV. A build without OpenCV has no module: asking for a video is then a named error.
#pragma once

#include "codec/core/image/image.hpp"
#include "format/error.hpp"

#include <filesystem>
#include <string>

namespace facemorph::tools {

class VideoFile {
 public:
  // Opens `path` for size×size frames at `fps`. Throws kUnsupported without the module, kIo when the
  // file cannot be opened.
  VideoFile(const std::filesystem::path& path, int size, double fps);
  ~VideoFile();
  VideoFile(const VideoFile&) = delete;
  VideoFile& operator=(const VideoFile&) = delete;

  // One RGB frame of size×size (throws kInvalidArgument for another shape, kIo when writing fails).
  void write(const Image& frame);
  // Finishes the file (also done by the destructor).
  void close();

 private:
  std::filesystem::path path_;
  int size_ = 0;
  void* video_ = nullptr;
  int (*write_)(void*, const uint8_t*, int) = nullptr;
  void (*close_)(void*) = nullptr;
};

}  // namespace facemorph::tools
