#include "codec/encoder/keyframes/normal_offsets.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <random>
#include <vector>

namespace facemorph {
namespace {

// The blocks give the bits of the Eigen expression the selection used to evaluate node by node
// (and whose keyframe choices the files then depend on): every key count a spline blends, a node
// count that is not a whole number of blocks, poses of every orientation.
TEST(NormalOffsets, EqualTheEigenExpressionToTheBit) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> uniform(-1, 1);
  const size_t count = 1000;
  for (int key_count = 1; key_count <= 5; ++key_count) {
    std::vector<std::vector<Eigen::Vector3f>> keys(static_cast<size_t>(key_count), std::vector<Eigen::Vector3f>(count));
    for (auto& key : keys)
      for (auto& p : key) p = Eigen::Vector3f(float(uniform(rng)), float(uniform(rng)), float(uniform(rng))) * 80.0f;
    std::vector<Eigen::Vector3f> normals(count);
    std::vector<Vec3> world(count);
    for (size_t v = 0; v < count; ++v) {
      normals[v] = Eigen::Vector3f(float(uniform(rng)), float(uniform(rng)), float(uniform(rng))).normalized();
      world[v] = Vec3(uniform(rng), uniform(rng), uniform(rng)) * 90.0;
    }
    std::vector<double> weights(static_cast<size_t>(key_count));
    for (double& w : weights) w = uniform(rng);
    RigidPose pose;
    pose.rotation = Eigen::AngleAxisd(uniform(rng) * 3, Vec3(uniform(rng), uniform(rng), uniform(rng)).normalized()).toRotationMatrix();
    pose.translation = Vec3(uniform(rng), uniform(rng), uniform(rng)) * 10.0;
    std::vector<const Eigen::Vector3f*> key_data;
    for (const auto& key : keys) key_data.push_back(key.data());
    std::vector<double> offsets(count);
    predicted_normal_offsets(key_data, weights, pose, world.data(), normals.data(), count, offsets.data());
    for (size_t v = 0; v < count; ++v) {
      Vec3 local = Vec3::Zero();
      for (size_t i = 0; i < keys.size(); ++i) local += weights[i] * keys[i][v].cast<double>();
      // The normal as SelectionFrame::normal_at gives it, a Vec3: Eigen's dot of two plain vectors
      // adds (x + y) + z; against a cast expression it added x + (y + z).
      const Vec3 normal = normals[v].cast<double>();
      const double expected = (pose.apply(local) - world[v]).dot(normal);
      ASSERT_EQ(offsets[v], expected) << key_count << " keys, node " << v;
    }
  }
}

}  // namespace
}  // namespace facemorph
