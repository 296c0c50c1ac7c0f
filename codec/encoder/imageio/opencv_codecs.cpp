#include "codec/encoder/imageio/opencv_codecs.hpp"

#include "format/error.hpp"

#include <dlfcn.h>

#include <optional>

namespace facemorph {

namespace {

// The two functions' names as g++ mangles their declarations (checked where the library is loaded:
// a missing one is a named error, never a wrong call).
constexpr const char* kImdecode = "_ZN2cv8imdecodeERKNS_11_InputArrayEi";
constexpr const char* kImencode =
    "_ZN2cv8imencodeERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEERKNS_11_InputArrayERSt6vectorIhSaIhEERKSB_IiSaIiEE";

struct Loaded {
  std::optional<OpenCvImageCodecs> codecs;
  std::string error;
};

Loaded load() {
  Loaded loaded;
  // By soname first (the dynamic linker's search, as linking would have found it), then the file
  // the build linked against.
  void* library = dlopen(FACEMORPH_OPENCV_IMGCODECS_SONAME, RTLD_NOW | RTLD_LOCAL);
  if (!library) library = dlopen(FACEMORPH_OPENCV_IMGCODECS_FILE, RTLD_NOW | RTLD_LOCAL);
  if (!library) {
    const char* why = dlerror();
    loaded.error = std::string("reading and writing images needs OpenCV's ") + FACEMORPH_OPENCV_IMGCODECS_SONAME + " (" +
                   (why ? why : "not found") + ")";
    return loaded;
  }
  OpenCvImageCodecs codecs{};
  codecs.imdecode = reinterpret_cast<decltype(codecs.imdecode)>(dlsym(library, kImdecode));
  codecs.imencode = reinterpret_cast<decltype(codecs.imencode)>(dlsym(library, kImencode));
  if (!codecs.imdecode || !codecs.imencode) {
    loaded.error = std::string(FACEMORPH_OPENCV_IMGCODECS_SONAME) + " lacks cv::imdecode or cv::imencode as this build declares them";
    return loaded;
  }
  loaded.codecs = codecs;
  return loaded;
}

}  // namespace

const OpenCvImageCodecs& opencv_image_codecs(const std::string& what) {
  static const Loaded loaded = load();  // the library stays loaded for the process
  if (!loaded.codecs) throw Error(ErrorCode::kUnsupported, what + ": " + loaded.error);
  return *loaded.codecs;
}

}  // namespace facemorph
