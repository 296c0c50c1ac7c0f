// OpenCV's image codecs (libopencv_imgcodecs), loaded the first time an image is read or written.
// Linked like the rest of OpenCV, it brought GDAL and its tree with it: 112 more shared libraries
// and 0.1 s of CPU at every start of every encoder tool, twice for fmenc and fmbench (their start
// with huge pages, tools/tool_support.hpp), whether or not the capture had a texture
// (spec/method.md §3.3, *OpenCV's image codecs on demand*).
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace facemorph {

// cv::imdecode and cv::imencode, as declared in <opencv2/imgcodecs.hpp>, from the library the
// encoder was built against (its soname pins the ABI).
struct OpenCvImageCodecs {
  cv::Mat (*imdecode)(const cv::_InputArray& buffer, int flags);
  bool (*imencode)(const std::string& extension, const cv::_InputArray& image, std::vector<uchar>& buffer, const std::vector<int>& params);
};

// Loaded once for the process and kept. Throws kUnsupported naming the library where it cannot be
// loaded or lacks either function; `what` (the file being read or written) leads the message.
const OpenCvImageCodecs& opencv_image_codecs(const std::string& what);

}  // namespace facemorph
