#include "aos/sim/occluders.h"

#include <algorithm>
#include <cmath>

#include "aos/sim/random.h"

namespace aos {

using sim::Hash;
using sim::Random;
using sim::Stream;

VoxelGrid MakeVoxelGrid(const VoxelSpec& spec, uint32_t seed) {
  VoxelGrid grid;
  grid.grid = spec.grid;
  for (int i = 0; i < 3; ++i) {
    grid.box_min[i] = spec.center[i] - 0.5 * spec.size[i];
    grid.cell[i] = spec.size[i] / spec.grid[i];
  }
  const int nx = spec.grid[0], ny = spec.grid[1], nz = spec.grid[2];
  if (spec.density <= 0.0) return grid;
  // P(cell occupied) so that P(column empty) = (1 - q)^nz = 1 - density.
  const double log_empty = std::log1p(-spec.density) / nz;  // log(1 - q) < 0
  grid.cells.reserve(static_cast<size_t>(-log_empty * nz * nx * ny * 1.1) + 16);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      Random random(Hash(seed, Stream::kVoxels, static_cast<uint64_t>(y) * nx + x));
      // Gaps between occupied cells are geometric: P(gap = k) = (1 - q)^k q.
      int z = -1;
      bool any = false;
      while (true) {
        const double u = 1.0 - random.Uniform();  // (0, 1]
        const double gap = std::floor(std::log(u) / log_empty);
        if (!(gap < nz - z - 1)) break;
        z += 1 + static_cast<int>(gap);
        grid.cells.push_back(VoxelGrid::Pack(x, y, z));
        any = true;
      }
      grid.blocked_columns += any ? 1 : 0;
    }
  }
  return grid;
}

namespace {

using Vec3f = std::array<float, 3>;

Vec3f ToFloat(const Vec3d& v) {
  return Vec3f{static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

// A unit vector uniform on the sphere.
Vec3d RandomDirection(Random& random) {
  const double z = random.Uniform(-1.0, 1.0);
  const double phi = random.Uniform(0.0, 6.283185307179586);
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vec3d(r * std::cos(phi), r * std::sin(phi), z);
}

}  // namespace

TreeMesh MakeTrees(const TreeSpec& spec, const GroundSpec& ground,
                   const std::array<double, 4>& area, uint32_t seed) {
  TreeMesh mesh;
  const double area_m2 = (area[2] - area[0]) * (area[3] - area[1]);
  mesh.trees = std::llround(spec.per_hectare * area_m2 / 1e4);
  std::vector<std::array<uint32_t, 4>> trunk_quads;
  std::vector<float> trunk_brightness;
  constexpr int kTrunkSides = 6;
  for (int64_t i = 0; i < mesh.trees; ++i) {
    Random random(Hash(seed, Stream::kTrees, static_cast<uint64_t>(i)));
    const double x = random.Uniform(area[0], area[2]);
    const double y = random.Uniform(area[1], area[3]);
    const double base = ground.HeightAt(x, y);
    const double height = random.Uniform(spec.height[0], spec.height[1]);
    const double radius = random.Uniform(spec.crown_radius[0], spec.crown_radius[1]);
    const double crown_half = 0.5 * spec.crown_fraction * height;
    const Vec3d crown_center(x, y, base + height - crown_half);
    // Leaves: centres uniform in the crown ellipsoid, orientations uniform.
    const double half = 0.5 * spec.leaf_size;
    for (int leaf = 0; leaf < spec.leaves_per_tree; ++leaf) {
      Vec3d offset;
      do {
        offset = Vec3d(random.Uniform(-1, 1), random.Uniform(-1, 1), random.Uniform(-1, 1));
      } while (glm::dot(offset, offset) > 1.0);
      const Vec3d centre = crown_center + Vec3d(radius, radius, crown_half) * offset;
      const Vec3d normal = RandomDirection(random);
      const Vec3d helper = std::abs(normal.z) < 0.9 ? Vec3d(0, 0, 1) : Vec3d(1, 0, 0);
      const Vec3d a = glm::normalize(glm::cross(normal, helper)) * half;
      const Vec3d b = glm::cross(normal, a);
      const uint32_t first = static_cast<uint32_t>(mesh.vertices.size());
      mesh.vertices.push_back(ToFloat(centre - a - b));
      mesh.vertices.push_back(ToFloat(centre + a - b));
      mesh.vertices.push_back(ToFloat(centre + a + b));
      mesh.vertices.push_back(ToFloat(centre - a + b));
      mesh.quads.push_back({first, first + 1, first + 2, first + 3});
      mesh.brightness.push_back(
          static_cast<float>(1.0 + spec.albedo_variation * random.Uniform(-1.0, 1.0)));
    }
    // Trunk: a 6-sided prism from below the ground to the crown centre.
    const uint32_t first = static_cast<uint32_t>(mesh.vertices.size());
    for (int s = 0; s < kTrunkSides; ++s) {
      const double angle = 6.283185307179586 * s / kTrunkSides;
      const double dx = spec.trunk_radius * std::cos(angle), dy = spec.trunk_radius * std::sin(angle);
      mesh.vertices.push_back(ToFloat(Vec3d(x + dx, y + dy, base - 0.5)));
      mesh.vertices.push_back(ToFloat(Vec3d(x + dx, y + dy, crown_center.z)));
    }
    for (int s = 0; s < kTrunkSides; ++s) {
      const uint32_t a = first + 2 * s, b = first + 2 * ((s + 1) % kTrunkSides);
      trunk_quads.push_back({a, b, b + 1, a + 1});
      trunk_brightness.push_back(1.0f);
    }
  }
  mesh.leaf_quads = static_cast<int64_t>(mesh.quads.size());
  mesh.trunk_quads = static_cast<int64_t>(trunk_quads.size());
  mesh.quads.insert(mesh.quads.end(), trunk_quads.begin(), trunk_quads.end());
  mesh.brightness.insert(mesh.brightness.end(), trunk_brightness.begin(), trunk_brightness.end());
  return mesh;
}

}  // namespace aos
