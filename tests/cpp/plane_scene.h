#pragma once
// A test-only analytic scene: textured planes ray-cast with point sampling at pixel centres (no
// anti-aliasing), so a view's pixel holds exactly the texture value where the pixel-centre ray
// first hits an opaque layer. The renderer's truth tests use it to place a known texture exactly
// on the focal plane (any orientation) or a bright point off it.
#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <utility>
#include <vector>

#include "aos/geometry/pinhole.h"
#include "aos/image/image.h"
#include "aos/util/error.h"

namespace aos {

// One plane of the scene. `shade` gets the hit point and writes `channels` values in the
// output's units (0..255 for 8-bit, 0..65535 for 16-bit, anything for float); it returns false
// where the layer is transparent (the ray goes on).
struct SceneLayer {
  Plane plane;
  std::function<bool(const Vec3d& point, float* value)> shade;
};

struct SyntheticScene {
  std::vector<SceneLayer> layers;
  int channels = 1;
  float background = 0.0f;  // value where a ray hits no opaque layer
};

namespace plane_scene_detail {

inline float ToStored(float value, PixelType type) {
  switch (type) {
    case PixelType::kU8: return std::clamp(std::round(value), 0.0f, 255.0f);
    case PixelType::kU16: return std::clamp(std::round(value), 0.0f, 65535.0f);
    default: return value;
  }
}

template <typename T>
inline void Store(Image& image, int x, int y, const float* values, int channels) {
  T* pixel = image.At<T>(x, y);
  for (int c = 0; c < channels; ++c) pixel[c] = static_cast<T>(ToStored(values[c], image.type()));
}

}  // namespace plane_scene_detail

// Renders one view of `scene`. Integer types are rounded and clamped to their range.
inline Image RenderSyntheticView(const SyntheticScene& scene, const PinholeCamera& camera,
                          const Rigid3d& cam_from_world, PixelType type) {
  camera.Check("synthetic view");
  if (scene.channels < 1 || scene.channels > 4) ThrowInvalid("synthetic scene: channels 1..4");
  Image image(camera.width, camera.height, scene.channels, type, 1);
  const Mat3d world_from_cam_rotation = glm::transpose(cam_from_world.rotation);
  const Vec3d center = cam_from_world.Center();
  const int channels = scene.channels;
  const int64_t height = camera.height;
  std::exception_ptr error;  // a throwing shade() must not escape the parallel region
#pragma omp parallel for schedule(dynamic, 4)
  for (int64_t y = 0; y < height; ++y) {
    std::vector<std::pair<double, size_t>> hits;
    float value[4];
    try {
    for (int x = 0; x < camera.width; ++x) {
      const Vec3d direction =
          world_from_cam_rotation * camera.Unproject(Vec2d(x + 0.5, static_cast<double>(y) + 0.5));
      hits.clear();
      for (size_t i = 0; i < scene.layers.size(); ++i) {
        const Plane& plane = scene.layers[i].plane;
        const double denominator = glm::dot(plane.normal, direction);
        if (denominator == 0.0) continue;
        const double t = glm::dot(plane.normal, plane.point - center) / denominator;
        if (t > 0.0) hits.emplace_back(t, i);
      }
      std::sort(hits.begin(), hits.end());
      std::fill(value, value + 4, scene.background);
      for (const auto& [t, index] : hits) {
        float shaded[4] = {0, 0, 0, 0};
        if (scene.layers[index].shade(center + t * direction, shaded)) {
          std::copy(shaded, shaded + 4, value);
          break;
        }
      }
      const int xi = x, yi = static_cast<int>(y);
      switch (type) {
        case PixelType::kU8: plane_scene_detail::Store<uint8_t>(image, xi, yi, value, channels); break;
        case PixelType::kU16: plane_scene_detail::Store<uint16_t>(image, xi, yi, value, channels); break;
        case PixelType::kU32: plane_scene_detail::Store<uint32_t>(image, xi, yi, value, channels); break;
        case PixelType::kF32: plane_scene_detail::Store<float>(image, xi, yi, value, channels); break;
      }
    }
    } catch (...) {
#pragma omp critical(aos_synthetic_error)
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);
  image.FillBorder();
  return image;
}

}  // namespace aos
