#include "tools/video_file.hpp"

#include <dlfcn.h>

namespace facemorph::tools {

namespace {

constexpr const char* kModule = "libfacemorph_video.so";

// The module beside the running executable (the build's tools/ folder, or wherever the tools are
// copied together); loaded once and kept.
void* video_module() {
  static void* const handle = [] {
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    const std::filesystem::path module = ec ? std::filesystem::path(kModule) : self.parent_path() / kModule;
    return dlopen(module.c_str(), RTLD_NOW | RTLD_LOCAL);
  }();
  return handle;
}

}  // namespace

VideoFile::VideoFile(const std::filesystem::path& path, int size, double fps) : path_(path), size_(size) {
  void* module = video_module();
  if (!module) {
    throw Error(ErrorCode::kUnsupported,
                path.string() + ": writing a video needs " + kModule + " beside this tool (built when OpenCV's videoio is there)");
  }
  auto open = reinterpret_cast<void* (*)(const char*, int, double)>(dlsym(module, "facemorph_video_open"));
  write_ = reinterpret_cast<int (*)(void*, const uint8_t*, int)>(dlsym(module, "facemorph_video_write"));
  close_ = reinterpret_cast<void (*)(void*)>(dlsym(module, "facemorph_video_close"));
  if (!open || !write_ || !close_) throw Error(ErrorCode::kUnsupported, std::string(kModule) + " lacks the video functions");
  video_ = open(path.c_str(), size, fps);
  if (!video_) throw Error(ErrorCode::kIo, path.string() + ": cannot open a video writer");
}

VideoFile::~VideoFile() { close(); }

void VideoFile::write(const Image& frame) {
  if (frame.width != size_ || frame.height != size_ || frame.channels != 3) {
    throw Error(ErrorCode::kInvalidArgument, path_.string() + ": a video frame must be " + std::to_string(size_) + "² RGB");
  }
  if (write_(video_, frame.pixels.data(), size_) != 0) throw Error(ErrorCode::kIo, path_.string() + ": writing a video frame failed");
}

void VideoFile::close() {
  if (video_) close_(video_);
  video_ = nullptr;
}

}  // namespace facemorph::tools
