#pragma once
// Occluder geometry of a scene as plain data (no ray tracer): the random voxel volume and the
// procedural trees. Deterministic for a given scene seed (see random.h).
#include <array>
#include <cstdint>
#include <vector>

#include "aos/sim/scene.h"

namespace aos {

// Occupied cells of a voxel volume. Each cell is occupied independently with probability
// q = 1 - (1 - density)^(1 / grid_z), drawn column by column (geometric gaps, so generation costs
// O(occupied cells), not O(grid cells)); memory is 4 bytes per occupied cell.
struct VoxelGrid {
  Vec3d box_min{0.0};          // lower corner of the volume, metres
  Vec3d cell{1.0};             // cell size per axis, metres
  std::array<int, 3> grid{0, 0, 0};
  std::vector<uint32_t> cells;  // packed x | y << 10 | z << 20, by column (y, x) then z
  int64_t blocked_columns = 0;  // columns holding at least one occupied cell

  static uint32_t Pack(int x, int y, int z) {
    return static_cast<uint32_t>(x) | static_cast<uint32_t>(y) << 10 | static_cast<uint32_t>(z) << 20;
  }
  Vec3d CellMin(uint32_t packed) const {
    return box_min + cell * Vec3d(packed & 1023u, (packed >> 10) & 1023u, (packed >> 20) & 1023u);
  }
  // Fraction of the columns that hold an occupied cell (the realised nadir-blocked fraction).
  double NadirBlockedFraction() const {
    return static_cast<double>(blocked_columns) / (static_cast<double>(grid[0]) * grid[1]);
  }
};

VoxelGrid MakeVoxelGrid(const VoxelSpec& spec, uint32_t seed);

// Trees as one quad mesh: leaves first, then trunks (6-sided prisms, 6 quads each).
struct TreeMesh {
  std::vector<std::array<float, 3>> vertices;
  std::vector<std::array<uint32_t, 4>> quads;
  std::vector<float> brightness;  // per quad, multiplies the material albedo
  int64_t trees = 0;
  int64_t leaf_quads = 0;   // quads [0, leaf_quads) are leaves
  int64_t trunk_quads = 0;  // the rest are trunk faces
};

// Trees standing on `ground` inside `area` ([xmin, ymin, xmax, ymax]); count =
// round(per_hectare * area / 10^4), positions uniform.
TreeMesh MakeTrees(const TreeSpec& spec, const GroundSpec& ground, const std::array<double, 4>& area,
                   uint32_t seed);

}  // namespace aos
