#pragma once
// A small deterministic synthetic light field, generated in code: the built-in default scene of
// `aos-render demo`, and the test-data generator of the renderer's tests. It ray-casts textured
// planes with point sampling at pixel centres (no anti-aliasing), so a view's pixel holds exactly
// the texture value where the pixel-centre ray first hits an opaque layer.
//
// This is a stand-in until the Embree occlusion simulator exists (issue 3 replaces it).
#include <cstdint>
#include <functional>
#include <vector>

#include "aos/geometry/pinhole.h"
#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"

namespace aos {

// One plane of the scene. `shade` gets the hit point (local frame) and writes `channels` values
// in the output's units (0..255 for 8-bit, 0..65535 for 16-bit, anything for float); it returns
// false where the layer is transparent (the ray goes on).
struct SceneLayer {
  Plane plane;
  std::function<bool(const Vec3d& point, float* value)> shade;
};

struct SyntheticScene {
  std::vector<SceneLayer> layers;
  int channels = 1;
  float background = 0.0f;  // value where a ray hits no opaque layer
};

// Renders one view of `scene`. Integer types are rounded and clamped to their range.
Image RenderSyntheticView(const SyntheticScene& scene, const PinholeCamera& camera,
                          const Rigid3d& cam_from_world, PixelType type);

struct DefaultSceneOptions {
  int views_per_side = 11;       // views on a square grid, views_per_side^2 in all (>= 1)
  double spacing = 3.0;          // distance between neighbouring views, metres (> 0)
  double altitude = 35.0;        // camera height above the ground (z = 0), metres (> 0)
  int width = 256;               // frame size, pixels
  int height = 256;
  double fov_deg = 50.0;         // horizontal field of view of the frames, degrees
  double occluder_density = 0.6; // fraction of nadir rays the occluder layers block, [0, 1)
  std::vector<double> occluder_heights{8.0, 11.0, 14.0};  // heights of the leaf layers, metres
  double leaf_size = 0.5;        // side of a square leaf cell, metres (> 0)
  uint32_t seed = 1;             // seed of the occluder pattern
  void Check() const;
};

// The default scene: a textured ground at z = 0 (a 2 m checkerboard with three warm targets)
// under layers of square leaves, seen by a nadir-looking grid of 8-bit grey views (z up, image
// top = +y). Deterministic for given options.
SyntheticScene MakeDefaultScene(const DefaultSceneOptions& options);
LightField MakeDefaultLightField(const DefaultSceneOptions& options);

// A nadir-looking camera pose (looking down -z, image top towards +y) centred at `position`.
Rigid3d NadirCamFromWorld(const Vec3d& position);

}  // namespace aos
