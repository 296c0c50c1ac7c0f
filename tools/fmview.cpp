// fmview: renders a mesh to a PNG picture (textured, checkerboard over its UVs, or plain shaded),
// shaded smoothly by the decoder's vertex normals (--flat: each triangle by its own).
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"

#include "tools/tool_support.hpp"

int main(int argc, char** argv) {
  using namespace facemorph;
  CLI::App app("Render a mesh (OBJ/PLY) to a picture.", "fmview");
  std::string input, output, mode = "texture";
  RenderOptions options;
  double squares = 20;
  bool flat = false;
  options.yaw_degrees = kPreviewYawDegrees;  // as fmdec --preview turns the decoded frame
  app.add_option("mesh", input, "Mesh file (.obj or .ply)")->required();
  app.add_option("-o,--out", output, "Picture to write (.png or .jpg)")->required();
  app.add_option("--mode", mode, "texture | checker | plain")->capture_default_str();
  app.add_option("--squares", squares, "Checkerboard squares per unit of UV")->capture_default_str();
  app.add_option("--yaw", options.yaw_degrees, "Rotation about the vertical axis, degrees")->capture_default_str();
  app.add_option("--pitch", options.pitch_degrees, "Rotation about the horizontal axis, degrees")->capture_default_str();
  app.add_flag("--flat", flat, "Light each triangle by its own normal (shows the facets), not by the interpolated vertex normals");
  app.add_option("--size", options.width, "Picture width and height, pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  return tools::guarded_main(app, argc, argv, [&] {
    options.height = options.width;
    const TriangleMesh mesh = read_mesh(input, {.allow_missing_texture = mode != "texture"});
    Image texture;
    SurfaceShader shader;
    if (mode == "texture") {
      if (!mesh.texture.empty()) texture = read_image(mesh.texture);
      shader = texture_shader(mesh, texture);
    } else if (mode == "checker") {
      shader = checkerboard_shader(mesh, squares);
    } else if (mode == "plain") {
      shader = constant_shader({200, 200, 200});
    } else {
      throw Error(ErrorCode::kInvalidArgument, "--mode must be texture, checker or plain");
    }
    write_image(output, flat ? render(mesh, shader, options) : render(mesh, shader, options, shading_normals(mesh)));
    return 0;
  });
}
