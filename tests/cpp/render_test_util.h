#pragma once
// Test-only helpers shared by the focal stack, surface integral and merge tests: small synthetic
// light fields (plane_scene.h) and byte-exact image comparison.
#include <algorithm>
#include <cmath>
#include <limits>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aos/lightfield/lightfield.h"
#include "plane_scene.h"

namespace aos::test_util {

// A light field of nadir-looking views rendered from `scene` at the given camera centres.
inline LightField NadirLightField(const SyntheticScene& scene, const PinholeCamera& camera,
                                  const std::vector<Vec3d>& centres, PixelType type) {
  LightField light_field;
  for (size_t i = 0; i < centres.size(); ++i) {
    const Rigid3d pose = NadirCamFromWorld(centres[i]);
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera, pose,
                                         RenderSyntheticView(scene, camera, pose, type)));
  }
  return light_field;
}

// per_side x per_side camera centres `spacing` apart at `altitude`, centred on the z axis.
inline std::vector<Vec3d> GridCentres(int per_side, double spacing, double altitude) {
  std::vector<Vec3d> centres;
  const double half = 0.5 * (per_side - 1) * spacing;
  for (int j = 0; j < per_side; ++j) {
    for (int i = 0; i < per_side; ++i) {
      centres.emplace_back(-half + i * spacing, -half + j * spacing, altitude);
    }
  }
  return centres;
}

// An image of one value per channel everywhere, of any type.
inline Image ConstantImage(int width, int height, const std::vector<float>& values,
                           PixelType type = PixelType::kF32) {
  const int channels = static_cast<int>(values.size());
  Image image(width, height, channels, type, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        switch (type) {
          case PixelType::kU8: image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(values[c]); break;
          case PixelType::kU16: image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(values[c]); break;
          case PixelType::kU32: image.At<uint32_t>(x, y)[c] = static_cast<uint32_t>(values[c]); break;
          case PixelType::kF32: image.At<float>(x, y)[c] = values[c]; break;
        }
      }
    }
  }
  image.FillBorder();
  return image;
}

// A scene of one horizontal plane at `height` with a smooth, everywhere-textured pattern in
// 0..255 (so every pixel has a gradient and Sobel focus has something to find).
inline SyntheticScene TexturedGround(double height) {
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(height), [](const Vec3d& p, float* value) {
    value[0] = static_cast<float>(128.0 + 60.0 * std::sin(2.1 * p.x + 0.4) * std::cos(1.7 * p.y) +
                                  50.0 * std::sin(1.3 * p.x - 2.3 * p.y + 1.0));
    return true;
  }});
  return scene;
}

// Success when `a` and `b` have the same size, channels, type and pixel bytes; else names the
// first differing pixel.
inline ::testing::AssertionResult SameImage(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels() ||
      a.type() != b.type()) {
    return ::testing::AssertionFailure()
           << "shape differs: " << a.width() << "x" << a.height() << "x" << a.channels() << " "
           << PixelTypeName(a.type()) << " vs " << b.width() << "x" << b.height() << "x"
           << b.channels() << " " << PixelTypeName(b.type());
  }
  const size_t pixel_bytes = a.channels() * PixelTypeSize(a.type());
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      if (std::memcmp(a.RawAt(x, y), b.RawAt(x, y), pixel_bytes) != 0) {
        return ::testing::AssertionFailure() << "pixel (" << x << ", " << y << ") differs: "
                                             << a.Value(x, y) << " vs " << b.Value(x, y);
      }
    }
  }
  return ::testing::AssertionSuccess();
}

// The largest |a - b| over the pixels and channels of two float32 images: infinity when their
// shapes differ, NaN when a difference is NaN (so that EXPECT_LT fails on either).
inline double MaxAbsDifference(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels()) {
    return std::numeric_limits<double>::infinity();
  }
  double worst = 0.0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width() * a.channels(); ++x) {
      const double d = std::abs(double(a.At<float>(0, y)[x]) - b.At<float>(0, y)[x]);
      if (std::isnan(d)) return d;
      worst = std::max(worst, d);
    }
  }
  return worst;
}

// Success when no value of the float image is NaN or infinite.
inline ::testing::AssertionResult AllFinite(const Image& image, const std::string& what) {
  if (auto problem = DescribeNonFinite(image)) {
    return ::testing::AssertionFailure() << what << ": " << *problem;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace aos::test_util
