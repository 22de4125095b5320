#include "aos/render/focal_stack.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/image/preview.h"
#include "aos/lightfield/json_codec.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/json_file.h"
#include "aos/util/memory.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

using json = nlohmann::json;
using ojson = nlohmann::ordered_json;

constexpr int kMaxSlices = 100000;

Vec3d UnitNormal(const Plane& plane, const std::string& which) {
  const Vec3d& n = plane.normal;
  const double length = glm::length(n);
  if (!std::isfinite(length) || !(length > 0.0) || !std::isfinite(plane.point.x) ||
      !std::isfinite(plane.point.y) || !std::isfinite(plane.point.z)) {
    ThrowInvalid(which + ": point and normal must be finite and the normal non-zero");
  }
  return n / length;
}

std::string SliceName(const char* prefix, int index) {
  char name[64];
  std::snprintf(name, sizeof(name), "%s_%04d.tif", prefix, index);
  return name;
}

}  // namespace

void FocalStackOptions::Check(int view_count) const {
  render.Check(view_count);
  if (render.focal_surface) {
    ThrowInvalid("render.focal_surface: focal stacks on a surface (terrain-following slices) are "
                 "not supported yet; the slices are planes (first_plane .. last_plane)");
  }
  UnitNormal(first_plane, "first_plane");
  UnitNormal(last_plane, "last_plane");
  if (slices < 1 || slices > kMaxSlices) {
    ThrowInvalid("slices: must be 1.." + std::to_string(kMaxSlices) + " (got " +
                 std::to_string(slices) + ")");
  }
}

Plane InterpolatePlane(const Plane& first, const Plane& last, double s, const Vec3d& center) {
  const Vec3d n0 = UnitNormal(first, "first_plane");
  Vec3d n1 = UnitNormal(last, "last_plane");
  const double h0 = glm::dot(n0, first.point - center);
  double h1 = glm::dot(n1, last.point - center);
  if (glm::dot(n0, n1) < 0.0) {
    n1 = -n1;
    h1 = -h1;
  }
  // n0 + n1 has length >= sqrt(2) after the flip, so the blend never vanishes.
  const Vec3d n = glm::normalize((1.0 - s) * n0 + s * n1);
  const double h = (1.0 - s) * h0 + s * h1;
  return Plane{center + h * n, n};
}

std::vector<Plane> StackPlanes(const Plane& first, const Plane& last, int slices,
                               const Vec3d& center) {
  if (slices < 1) ThrowInvalid("slices: must be >= 1 (got " + std::to_string(slices) + ")");
  std::vector<Plane> planes;
  planes.reserve(static_cast<size_t>(slices));
  for (int i = 0; i < slices; ++i) {
    const double s = slices == 1 ? 0.5 : static_cast<double>(i) / (slices - 1);
    planes.push_back(InterpolatePlane(first, last, s, center));
  }
  return planes;
}

void FocalStack::Check(const std::string& where) const {
  const size_t n = planes.size();
  if (n == 0) ThrowInvalid(where + ": the stack has no slices");
  if (images.size() != n || counts.size() != n || (!variances.empty() && variances.size() != n)) {
    ThrowInvalid(where + ": planes, images, counts and variances differ in number");
  }
  for (size_t i = 0; i < n; ++i) {
    const std::string slice = where + ": slice " + std::to_string(i);
    const Plane& plane = planes[i];
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(plane.point[k]) || !std::isfinite(plane.normal[k])) {
        ThrowInvalid(slice + ": plane: point and normal must be finite");
      }
    }
    if (!(glm::length(plane.normal) > 0.0)) ThrowInvalid(slice + ": plane: normal must not be zero");
    const Image& image = images[i];
    if (image.width() != camera.width || image.height() != camera.height ||
        image.type() != PixelType::kF32) {
      ThrowInvalid(slice + ": image must be float32 of the camera's size " +
                   std::to_string(camera.width) + "x" + std::to_string(camera.height));
    }
    if (image.channels() != images.front().channels()) {
      ThrowInvalid(slice + ": has " + std::to_string(image.channels()) +
                   " channels, slice 0 has " + std::to_string(images.front().channels()));
    }
    if (counts[i].width() != camera.width || counts[i].height() != camera.height ||
        counts[i].channels() != 1 || counts[i].type() != PixelType::kU32) {
      ThrowInvalid(slice + ": count must be 1-channel uint32 of the camera's size");
    }
    if (!variances.empty() &&
        (variances[i].width() != camera.width || variances[i].height() != camera.height ||
         variances[i].channels() != 1 || variances[i].type() != PixelType::kF32)) {
      ThrowInvalid(slice + ": variance must be 1-channel float32 of the camera's size");
    }
    if (auto problem = DescribeNonFinite(image)) ThrowInvalid(slice + ": image: " + *problem);
    if (auto problem = DescribeOutOfStackRange(image)) {
      ThrowInvalid(slice + ": image: " + *problem);
    }
    if (!variances.empty()) {
      if (auto problem = DescribeNonFinite(variances[i])) {
        ThrowInvalid(slice + ": variance: " + *problem);
      }
      for (int y = 0; y < camera.height; ++y) {
        const float* row = variances[i].At<float>(0, y);
        for (int x = 0; x < camera.width; ++x) {
          if (row[x] < 0.0f) {
            ThrowInvalid(slice + ": variance: negative at pixel (" + std::to_string(x) + ", " +
                         std::to_string(y) + ")");
          }
        }
      }
    }
  }
}

void RenderFocalStackSlices(const LightField& light_field, const FocalStackOptions& options,
                            const SliceSink& on_slice, ProgressSink* progress) {
  options.Check(static_cast<int>(light_field.views.size()));
  const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, options.render);
  const std::vector<Plane> planes =
      StackPlanes(options.first_plane, options.last_plane, options.slices, cam_from_world.Center());
  ProgressStart(progress, "focal stack", options.slices);
  IntegralOptions render = options.render;
  for (int i = 0; i < options.slices; ++i) {
    if (ProgressCancelled(progress)) throw Cancelled();
    render.focal_plane = planes[static_cast<size_t>(i)];
    IntegralResult slice;
    try {
      slice = RenderIntegral(light_field, render);
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("slice " + std::to_string(i) + ": " + error.what());
    }
    on_slice(i, planes[static_cast<size_t>(i)], slice);
    ProgressAdvance(progress, 1);
  }
}

FocalStack RenderFocalStack(const LightField& light_field, const FocalStackOptions& options,
                            ProgressSink* progress) {
  FocalStack stack;
  stack.camera = VirtualCamera(light_field, options.render);
  if (!light_field.views.empty()) {
    // Every slice is kept: refuse a stack the machine cannot hold before rendering any of it.
    const uint64_t channels = static_cast<uint64_t>(light_field.views.front().image.channels());
    CheckMemoryBudget(
        SaturatingProduct({static_cast<uint64_t>(std::max(options.slices, 0)),
                           static_cast<uint64_t>(stack.camera.width),
                           static_cast<uint64_t>(stack.camera.height),
                           channels * 4 + 4 + (options.render.variance ? 4 : 0)}),
        "slices: " + std::to_string(options.slices) + " slices of " +
            std::to_string(stack.camera.width) + " x " + std::to_string(stack.camera.height) +
            " pixels",
        "each slice's float32 image, uint32 count" +
            std::string(options.render.variance ? " and float32 variance" : ""));
  }
  // The resolved virtual camera (fov and size may come from the pose view).
  stack.render = WithResolvedCamera(light_field, options.render);
  RenderFocalStackSlices(
      light_field, options,
      [&](int, const Plane& plane, IntegralResult& slice) {
        stack.cam_from_world = slice.cam_from_world;
        stack.planes.push_back(plane);
        stack.images.push_back(std::move(slice.image));
        stack.counts.push_back(std::move(slice.count));
        if (options.render.variance) stack.variances.push_back(std::move(slice.variance));
      },
      progress);
  return stack;
}

namespace {

// stack_preview.png: every slice stretched with one range (the 1st..99th percentile of all
// slices' covered samples, so slices compare), and count_preview.png: the count maps with 0 ->
// black and the largest count -> white; contact sheets of up to 10 tiles per row, each at most
// 256 pixels wide. The ranges are in the PNGs' descriptions.
void WriteStackPreviews(const fs::path& folder, const FocalStack& stack) {
  std::vector<const Image*> images;
  std::vector<const Image*> covered;
  double max_count = 0.0;
  for (int i = 0; i < stack.size(); ++i) {
    images.push_back(&stack.images[static_cast<size_t>(i)]);
    covered.push_back(&stack.counts[static_cast<size_t>(i)]);
    const Image& count = stack.counts[static_cast<size_t>(i)];
    for (int y = 0; y < count.height(); ++y) {
      for (int x = 0; x < count.width(); ++x) max_count = std::max(max_count, count.Value(x, y));
    }
  }
  const PreviewRange range = PercentileRange(images, covered, 1.0, 99.0);
  const PreviewRange count_range{0.0, std::max(1.0, max_count)};
  std::vector<Image> slice_tiles;
  std::vector<Image> count_tiles;
  for (int i = 0; i < stack.size(); ++i) {
    slice_tiles.push_back(MappedPreview(*images[static_cast<size_t>(i)],
                                        covered[static_cast<size_t>(i)], range));
    count_tiles.push_back(MappedPreview(*covered[static_cast<size_t>(i)], nullptr, count_range));
  }
  constexpr int kColumns = 10;
  constexpr int kTileWidth = 256;
  WriteImageOptions write;
  write.description = "aos focal-stack preview: slices 0.." + std::to_string(stack.size() - 1) +
                      " left to right, top to bottom; values " + FormatNumber(range.lo) + ".." +
                      FormatNumber(range.hi) + " (1st..99th percentile of all slices) mapped "
                      "to 0..255; uncovered pixels black";
  WriteImage((folder / "stack_preview.png").string(),
             ContactSheet(slice_tiles, kColumns, kTileWidth), write);
  write.description = "aos count preview: views per pixel, 0 (black) .. " +
                      FormatNumber(count_range.hi) + " (white), slices as in stack_preview.png";
  WriteImage((folder / "count_preview.png").string(),
             ContactSheet(count_tiles, kColumns, kTileWidth), write);
}

}  // namespace

void WriteFocalStack(const std::string& folder, const FocalStack& stack) {
  stack.Check("focal stack");
  PendingFolder pending(folder);
  const fs::path temp = pending.TempPath();
  ojson j;
  j["format"] = "aos-focal-stack";
  j["version"] = 1;
  j["camera"] = CameraToJson(LensCamera::FromPinhole(stack.camera));
  j["cam_from_world"] = PoseToJson(stack.cam_from_world);
  const IntegralOptions& r = stack.render;
  j["render"] = {{"fov_deg", r.fov_deg},
                 {"aperture_radius", std::isfinite(r.aperture_radius) ? ojson(r.aperture_radius)
                                                                      : ojson("inf")},
                 {"min_view_angle_deg", r.min_view_angle_deg},
                 {"view_indices", r.view_indices}};
  ojson slices = ojson::array();
  for (int i = 0; i < stack.size(); ++i) {
    const Plane& plane = stack.planes[static_cast<size_t>(i)];
    ojson slice = {{"plane", PlaneToJson(plane)},
                   {"image", SliceName("slice", i)},
                   {"count", SliceName("count", i)}};
    WriteImage((temp / SliceName("slice", i)).string(), stack.images[static_cast<size_t>(i)]);
    WriteImage((temp / SliceName("count", i)).string(), stack.counts[static_cast<size_t>(i)]);
    if (!stack.variances.empty()) {
      slice["variance"] = SliceName("variance", i);
      WriteImage((temp / SliceName("variance", i)).string(),
                 stack.variances[static_cast<size_t>(i)]);
    }
    slices.push_back(slice);
  }
  j["slices"] = slices;
  WriteTextFileAtomic((temp / "stack.json").string(), j.dump(2) + "\n");
  WriteStackPreviews(temp, stack);
  pending.Commit();
}

namespace {
FocalStack FocalStackFromJson(const json& j, const fs::path& base, const std::string& file);
}  // namespace

std::optional<std::string> DescribeOutOfStackRange(const Image& image) {
  if (image.type() != PixelType::kF32) return std::nullopt;
  for (int y = 0; y < image.height(); ++y) {
    const float* row = image.At<float>(0, y);
    for (int i = 0; i < image.width() * image.channels(); ++i) {
      if (std::fabs(row[i]) > kMaxStackMagnitude) {
        return "pixel (" + std::to_string(i / image.channels()) + ", " + std::to_string(y) +
               ") channel " + std::to_string(i % image.channels()) + " is " +
               FormatNumber(row[i]) + ", beyond +-1e15 (the merge's focus measures would "
               "overflow float32)";
      }
    }
  }
  return std::nullopt;
}

FocalStack ReadFocalStack(const std::string& folder) {
  const fs::path base(folder);
  const std::string file = (base / "stack.json").string();
  const json j = ParseJsonFile(file);
  return WithJsonErrorsNamed(file, [&] { return FocalStackFromJson(j, base, file); });
}

namespace {

FocalStack FocalStackFromJson(const json& j, const fs::path& base, const std::string& file) {
  const JsonPath top(file);
  if (!j.is_object() || !j.contains("format") || j["format"] != "aos-focal-stack") {
    ThrowInvalid(Where(file, "format: must be \"aos-focal-stack\""));
  }
  RequireKnownKeys(j, {"format", "version", "camera", "cam_from_world", "render", "slices"}, top);
  if (ReadJsonNumber(RequireMember(j, "version", top), top / "version") != 1) {
    (top / "version").Fail("must be 1");
  }
  FocalStack stack;
  const LensCamera camera = ReadCameraJson(RequireMember(j, "camera", top), top / "camera");
  if (camera.model != LensModel::kPinhole) {
    (top / "camera" / "model").Fail("a focal stack's camera is a pinhole, not " +
                                    std::string(LensModelName(camera.model)));
  }
  stack.camera = camera.Pinhole();
  stack.cam_from_world =
      ReadPoseJson(RequireMember(j, "cam_from_world", top), top / "cam_from_world");
  stack.render.width = stack.camera.width;
  stack.render.height = stack.camera.height;
  stack.render.cam_from_world = stack.cam_from_world;
  if (j.contains("render")) {
    const json& render = j["render"];
    const JsonPath at = top / "render";
    RequireKnownKeys(render, {"fov_deg", "aperture_radius", "min_view_angle_deg", "view_indices"},
                     at);
    stack.render.fov_deg = ReadJsonNumber(RequireMember(render, "fov_deg", at), at / "fov_deg");
    const json& radius = RequireMember(render, "aperture_radius", at);
    if (radius.is_string() && radius.get<std::string>() == "inf") {
      stack.render.aperture_radius = std::numeric_limits<double>::infinity();
    } else {
      stack.render.aperture_radius = ReadJsonNumber(radius, at / "aperture_radius");
    }
    stack.render.min_view_angle_deg =
        ReadJsonNumber(RequireMember(render, "min_view_angle_deg", at), at / "min_view_angle_deg");
    const json& views = RequireMember(render, "view_indices", at);
    if (!views.is_array()) (at / "view_indices").Fail("must be an array");
    for (size_t i = 0; i < views.size(); ++i) {
      if (!views[i].is_number_integer()) (at / "view_indices" / i).Fail("must be an integer");
      stack.render.view_indices.push_back(views[i].get<int>());
    }
  } else {
    stack.render.fov_deg = stack.camera.FovXDeg();
  }
  const json& slices = RequireMember(j, "slices", top);
  if (!slices.is_array() || slices.empty()) (top / "slices").Fail("must be a non-empty array");
  bool has_variance = true;
  for (size_t i = 0; i < slices.size(); ++i) has_variance = has_variance && slices[i].contains("variance");
  stack.render.variance = has_variance;  // rendered with variance: its images are stored
  for (size_t i = 0; i < slices.size(); ++i) {
    const JsonPath at = top / "slices" / i;
    const json& slice = slices[i];
    RequireKnownKeys(slice, {"plane", "image", "count", "variance"}, at);
    stack.planes.push_back(ReadPlaneJson(RequireMember(slice, "plane", at), at / "plane"));
    // Each file is checked as it is read, so that errors name it (FocalStack::Check then finds
    // nothing more to say about sizes and types).
    std::string path;
    auto read = [&](const std::string& key, int channels, const char* what) {
      const json& name = RequireMember(slice, key.c_str(), at);
      if (!name.is_string()) (at / key).Fail("must be a string, got " + DescribeJson(name));
      path = (base / name.get<std::string>()).string();
      Image image = ReadImage(path);
      if (image.width() != stack.camera.width || image.height() != stack.camera.height ||
          (channels > 0 && image.channels() != channels)) {
        ThrowInvalid((at / key).Text() + ": " + path + ": is " +
                     std::to_string(image.width()) + "x" + std::to_string(image.height()) + "x" +
                     std::to_string(image.channels()) + ", expected " + what + " of " +
                     std::to_string(stack.camera.width) + "x" +
                     std::to_string(stack.camera.height) + " (the stack's camera)");
      }
      return image;
    };
    stack.images.push_back(read("image", i == 0 ? 0 : stack.images[0].channels(),
                                i == 0 ? "an image" : "an image with slice 0's channels"));
    if (stack.images.back().type() != PixelType::kF32) {
      ThrowInvalid((at / "image").Text() + ": " + path + ": holds " +
                   PixelTypeName(stack.images.back().type()) + " samples, expected float32");
    }
    if (auto problem = DescribeOutOfStackRange(stack.images.back())) {
      ThrowInvalid((at / "image").Text() + ": " + path + ": " + *problem);
    }
    if (i == 0) {
      // Every slice stays in memory: refuse before decoding the rest (image of slice 0's
      // channels, float; count and variance, 4 bytes each).
      const uint64_t channels = static_cast<uint64_t>(stack.images[0].channels());
      const uint64_t per_pixel = 4 * channels + 4 + (has_variance ? 4 : 0);
      CheckMemoryBudget(
          SaturatingProduct({static_cast<uint64_t>(slices.size()),
                             static_cast<uint64_t>(stack.camera.width),
                             static_cast<uint64_t>(stack.camera.height), per_pixel}),
          file + ": " + std::to_string(slices.size()) + " slices of " +
              std::to_string(stack.camera.width) + "x" + std::to_string(stack.camera.height),
          "images, counts" + std::string(has_variance ? " and variances" : "") + " in memory");
    }
    Image count = read("count", 1, "a 1-channel count map");
    if (count.type() == PixelType::kF32 && count.channels() == 1) {
      // 32-bit integer files come back as float (image_io.h); counts are exact below 2^24.
      Image converted(count.width(), count.height(), 1, PixelType::kU32);
      for (int y = 0; y < count.height(); ++y) {
        for (int x = 0; x < count.width(); ++x) {
          const float value = count.At<float>(x, y)[0];
          if (!(value >= 0.0f && value < 16777216.0f) || value != std::floor(value)) {
            ThrowInvalid((at / "count").Text() + ": " + path + ": pixel (" +
                         std::to_string(x) + ", " + std::to_string(y) + ") is not a count");
          }
          converted.At<uint32_t>(x, y)[0] = static_cast<uint32_t>(value);
        }
      }
      count = std::move(converted);
    }
    if (count.type() != PixelType::kU32) {
      ThrowInvalid((at / "count").Text() + ": " + path + ": holds " +
                   PixelTypeName(count.type()) + " samples, expected 32-bit counts");
    }
    stack.counts.push_back(std::move(count));
    if (has_variance) {
      stack.variances.push_back(read("variance", 1, "a 1-channel variance map"));
      if (stack.variances.back().type() != PixelType::kF32) {
        ThrowInvalid((at / "variance").Text() + ": " + path + ": holds " +
                     PixelTypeName(stack.variances.back().type()) +
                     " samples, expected float32");
      }
    }
  }
  stack.Check(file);
  return stack;
}

}  // namespace

}  // namespace aos
