#include "tools/field_export.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace facemorph::tools {

namespace {

namespace fs = std::filesystem;

struct Plane {
  std::string name;
  std::vector<float> pixels;
};

// One value per interior node placed at its lattice cell; rim nodes are on the circle, not the
// lattice, and go to the CSV instead.
Plane grid_plane(const DiskGrid& grid, const std::string& name, const std::vector<double>& values) {
  Plane plane{name, std::vector<float>(static_cast<size_t>(grid.n) * static_cast<size_t>(grid.n), 0.0f)};
  for (int node = 0; node < grid.interior_count; ++node) {
    const auto [i, j] = grid.cell[static_cast<size_t>(node)];
    // Image rows go down, v up: row N-1-j.
    plane.pixels[static_cast<size_t>(grid.n - 1 - j) * static_cast<size_t>(grid.n) + static_cast<size_t>(i)] =
        static_cast<float>(values[static_cast<size_t>(node)]);
  }
  return plane;
}

void write_exr(const fs::path& path, int n, const std::vector<Plane>& planes, const std::string& description) {
  const fs::path temporary = format::temporary_sibling(path);
  try {
    Imf::Header header(n, n);
    header.insert("comments", Imf::StringAttribute(description));
    Imf::FrameBuffer buffer;
    for (const Plane& plane : planes) {
      header.channels().insert(plane.name, Imf::Channel(Imf::FLOAT));
      buffer.insert(plane.name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(plane.pixels.data())), sizeof(float),
                                           sizeof(float) * static_cast<size_t>(n)));
    }
    Imf::OutputFile file(temporary.string().c_str(), header);
    file.setFrameBuffer(buffer);
    file.writePixels(n);
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(temporary, ec);
    throw Error(ErrorCode::kIo, path.string() + ": " + e.what());
  }
  format::commit_temporary(temporary, path);
}

std::string vectors_csv(const std::string& header, const std::vector<Vec3>& vectors, const std::vector<int32_t>* nodes) {
  std::ostringstream out;
  out.precision(9);
  out << header << "\n";
  for (size_t k = 0; k < vectors.size(); ++k) {
    out << (nodes ? (*nodes)[k] : static_cast<int32_t>(k)) << "," << vectors[k].x() << "," << vectors[k].y() << "," << vectors[k].z()
        << "\n";
  }
  return out.str();
}

}  // namespace

std::vector<fs::path> export_keyframe_fields(const Sequence& sequence, const fs::path& folder) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) throw Error(ErrorCode::kIo, folder.string() + ": cannot create the folder: " + ec.message());
  const DiskGrid grid = make_disk_grid(sequence.grid_n);
  std::vector<fs::path> written;
  for (size_t k = 0; k < sequence.keyframes.size(); ++k) {
    const Keyframe& key = sequence.keyframes[k];
    const GridFields& f = key.fields;
    char stem[32];
    std::snprintf(stem, sizeof stem, "keyframe_%03zu", k);
    std::vector<Plane> planes;
    std::vector<double> inside(static_cast<size_t>(grid.interior_count), 1.0);
    planes.push_back(grid_plane(grid, "A", inside));
    if (f.representation == Representation::kXYZ) {
      for (int c = 0; c < 3; ++c) {
        std::vector<double> component;
        for (const Vec3& p : f.positions) component.push_back(p[c]);
        planes.push_back(grid_plane(grid, std::string(1, "XYZ"[c]), component));
      }
    } else {
      planes.push_back(grid_plane(grid, "H", f.mean_curvature));
      planes.push_back(grid_plane(grid, "log_lambda", f.log_conformal_factor));
      if (f.representation == Representation::kHLT) {
        planes.push_back(grid_plane(grid, "tangential_u", f.tangential_u));
        planes.push_back(grid_plane(grid, "tangential_v", f.tangential_v));
      }
    }
    if (!key.hole_level.empty()) planes.push_back(grid_plane(grid, "hole_level", key.hole_level));
    char description[160];
    std::snprintf(description, sizeof description, "facemorph keyframe %zu at t = %.6f s; grid N = %d; %s fields; interior nodes only", k,
                  key.time, sequence.grid_n, representation_name(f.representation));
    const fs::path exr = folder / (std::string(stem) + ".exr");
    write_exr(exr, grid.n, planes, description);
    written.push_back(exr);
    const fs::path rim = folder / (std::string(stem) + "_rim.csv");
    format::write_file_atomically(rim, vectors_csv("rim_node,x,y,z", f.rim, nullptr));
    written.push_back(rim);
    if (!f.fixed_nodes.empty()) {
      const fs::path fixed = folder / (std::string(stem) + "_fixed.csv");
      format::write_file_atomically(fixed, vectors_csv("node,c0,c1,c2", f.fixed_laplacian, &f.fixed_nodes));
      written.push_back(fixed);
    }
    if (!key.texture.empty()) {
      const fs::path png = folder / (std::string(stem) + "_texture.png");
      write_png(png, key.texture);
      written.push_back(png);
    }
  }
  return written;
}

}  // namespace facemorph::tools
