#include "aos/sim/default_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include "aos/util/error.h"

namespace aos {
namespace {

// A well-mixed 64-bit hash (splitmix64 finaliser) for deterministic per-cell randomness.
uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Uniform in [0, 1) from a cell of a layer.
double CellRandom(uint32_t seed, int layer, int64_t ix, int64_t iy) {
  uint64_t h = Mix(seed);
  h = Mix(h ^ static_cast<uint64_t>(layer));
  h = Mix(h ^ static_cast<uint64_t>(ix));
  h = Mix(h ^ static_cast<uint64_t>(iy));
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

float ToStored(float value, PixelType type) {
  switch (type) {
    case PixelType::kU8: return std::clamp(std::round(value), 0.0f, 255.0f);
    case PixelType::kU16: return std::clamp(std::round(value), 0.0f, 65535.0f);
    default: return value;
  }
}

template <typename T>
void Store(Image& image, int x, int y, const float* values, int channels) {
  T* pixel = image.At<T>(x, y);
  for (int c = 0; c < channels; ++c) pixel[c] = static_cast<T>(ToStored(values[c], image.type()));
}

}  // namespace

Image RenderSyntheticView(const SyntheticScene& scene, const PinholeCamera& camera,
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
        case PixelType::kU8: Store<uint8_t>(image, xi, yi, value, channels); break;
        case PixelType::kU16: Store<uint16_t>(image, xi, yi, value, channels); break;
        case PixelType::kU32: Store<uint32_t>(image, xi, yi, value, channels); break;
        case PixelType::kF32: Store<float>(image, xi, yi, value, channels); break;
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

void DefaultSceneOptions::Check() const {
  if (views_per_side < 1) ThrowInvalid("views_per_side: must be >= 1");
  if (!(spacing > 0.0) || !std::isfinite(spacing)) ThrowInvalid("spacing: must be > 0 metres");
  if (!(altitude > 0.0) || !std::isfinite(altitude)) ThrowInvalid("altitude: must be > 0 metres");
  if (width < 1 || height < 1) ThrowInvalid("width/height: must be >= 1 pixel");
  if (!(fov_deg > 0.0 && fov_deg < 180.0)) ThrowInvalid("fov_deg: must be in (0, 180) degrees");
  if (!(occluder_density >= 0.0 && occluder_density < 1.0)) {
    ThrowInvalid("occluder_density: must be in [0, 1)");
  }
  if (!(leaf_size > 0.0) || !std::isfinite(leaf_size)) ThrowInvalid("leaf_size: must be > 0 metres");
  for (double h : occluder_heights) {
    if (!(h > 0.0 && h < altitude)) {
      ThrowInvalid("occluder_heights: each height must lie between the ground (0) and the "
                   "altitude (got " + FormatNumber(h) + ")");
    }
  }
}

Rigid3d NadirCamFromWorld(const Vec3d& position) {
  return LookAt(position, position - Vec3d(0, 0, 1), Vec3d(0, 1, 0));
}

SyntheticScene MakeDefaultScene(const DefaultSceneOptions& options) {
  options.Check();
  SyntheticScene scene;
  scene.channels = 1;
  scene.background = 0.0f;
  // Leaf layers, nearest to the cameras first does not matter: the renderer sorts hits.
  const int layers = static_cast<int>(options.occluder_heights.size());
  // Each layer blocks p of the nadir rays independently, so all together block 1 - (1 - p)^n.
  const double p = layers > 0 ? 1.0 - std::pow(1.0 - options.occluder_density, 1.0 / layers) : 0.0;
  for (int layer = 0; layer < layers; ++layer) {
    const double leaf = options.leaf_size;
    const uint32_t seed = options.seed;
    scene.layers.push_back(SceneLayer{
        Plane::AtHeight(options.occluder_heights[layer]),
        [=](const Vec3d& point, float* value) {
          const auto ix = static_cast<int64_t>(std::floor(point.x / leaf));
          const auto iy = static_cast<int64_t>(std::floor(point.y / leaf));
          const double r = CellRandom(seed, layer, ix, iy);
          if (r >= p) return false;
          value[0] = static_cast<float>(40.0 + 40.0 * (r / std::max(p, 1e-12)));  // cool leaves
          return true;
        }});
  }
  // Ground: a 2 m checkerboard with a gentle ripple and three warm targets (people lying down).
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d& point, float* value) {
    const bool odd = (static_cast<int64_t>(std::floor(point.x / 2.0)) +
                      static_cast<int64_t>(std::floor(point.y / 2.0))) & 1;
    double v = odd ? 130.0 : 100.0;
    v += 8.0 * std::sin(point.x * 0.9) * std::cos(point.y * 0.7);
    struct Target { double x, y, half_w, half_h; };
    const Target targets[] = {{-4.0, 3.0, 0.4, 0.9}, {5.0, -2.0, 0.9, 0.4}, {0.5, -6.0, 0.4, 0.9}};
    for (const Target& t : targets) {
      if (std::abs(point.x - t.x) <= t.half_w && std::abs(point.y - t.y) <= t.half_h) v = 235.0;
    }
    value[0] = static_cast<float>(v);
    return true;
  }});
  return scene;
}

LightField MakeDefaultLightField(const DefaultSceneOptions& options) {
  const SyntheticScene scene = MakeDefaultScene(options);
  const PinholeCamera camera = PinholeCamera::FromFov(options.width, options.height, options.fov_deg);
  LightField light_field;
  const int n = options.views_per_side;
  const double half = 0.5 * (n - 1) * options.spacing;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Vec3d position(-half + i * options.spacing, half - j * options.spacing,
                           options.altitude);
      const Rigid3d cam_from_world = NadirCamFromWorld(position);
      char name[32];
      std::snprintf(name, sizeof(name), "view_%02d_%02d", j, i);
      light_field.views.push_back(MakeView(name, camera, cam_from_world,
                                           RenderSyntheticView(scene, camera, cam_from_world,
                                                               PixelType::kU8)));
    }
  }
  return light_field;
}

}  // namespace aos
