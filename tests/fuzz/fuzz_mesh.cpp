// libFuzzer target: the OBJ and PLY parsers (the first byte picks which). Every input must give a
// mesh or a named facemorph::Error; nothing is read from or written to disk (a missing texture is
// allowed so the parser does not stop at the material).
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  facemorph::MeshReadOptions options;
  options.allow_missing_texture = true;
  try {
    if (data[0] == 'p') {
      facemorph::parse_ply({data, size}, "fuzz.ply", "/nonexistent", options);
    } else {
      facemorph::parse_obj({reinterpret_cast<const char*>(data), size}, "fuzz.obj", "/nonexistent", options);
    }
  } catch (const facemorph::Error&) {}
  return 0;
}
