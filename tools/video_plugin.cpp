// libfacemorph_video: the tools' MP4 writer (OpenCV's videoio) as a module loaded only when a video
// is asked for (tools/video_file.hpp). Linked into fmdec and fmplay directly, OpenCV's 240-odd shared
// libraries cost every start 0.15 s of dynamic linking — more than ten frames' decoding at N = 129 —
// whether or not a video is written.
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <cstdint>
#include <exception>
#include <new>

extern "C" {

// An MP4 (mp4v) writer of size×size RGB frames, or null when it cannot be opened.
__attribute__((visibility("default"))) void* facemorph_video_open(const char* path, int size, double fps) {
  try {
    auto* writer = new cv::VideoWriter(path, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, cv::Size(size, size));
    if (writer->isOpened()) return writer;
    delete writer;
  } catch (const std::exception&) {}
  return nullptr;
}

// Appends one frame of size×size×3 RGB bytes; 0 on success.
__attribute__((visibility("default"))) int facemorph_video_write(void* video, const uint8_t* rgb, int size) {
  try {
    const cv::Mat frame(size, size, CV_8UC3, const_cast<uint8_t*>(rgb));
    cv::Mat bgr;
    cv::cvtColor(frame, bgr, cv::COLOR_RGB2BGR);
    static_cast<cv::VideoWriter*>(video)->write(bgr);
    return 0;
  } catch (const std::exception&) {
    return 1;
  }
}

// Finishes the file and frees the writer.
__attribute__((visibility("default"))) void facemorph_video_close(void* video) { delete static_cast<cv::VideoWriter*>(video); }

}  // extern "C"
