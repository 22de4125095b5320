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
#include "aos/lightfield/options_json.h"
#include "aos/render/focal_surface_json.h"
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
  const bool follows = FollowsSurface(render);
  if (ground_plane && follows) {
    ThrowInvalid("ground_plane: give either render.focal_surface (a mesh, DEM or depth map: a "
                 "terrain-following stack) or ground_plane (planes parallel to the ground), not "
                 "both");
  }
  if (ground_plane) UnitNormal(*ground_plane, "ground_plane");
  CheckFieldRanges(*this);  // the table's ranges (focal_stack.h)
  if (render.surface_offset != 0.0) {
    ThrowInvalid("render.surface_offset: must be 0 in a stack (its slices lie at first_offset.."
                 "last_offset along up, or on the planes; got " +
                 FormatNumber(render.surface_offset) + ")");
  }
  if (!follows && !render.focal_surface.SameAs(IntegralOptions().focal_surface)) {
    // A plane would be ignored (the slices' planes replace it): refused, not dropped.
    ThrowInvalid("render.focal_surface: a plane here would be ignored: a stack's slices lie on "
                 "planes (first_plane .. last_plane, or around ground_plane); a "
                 "terrain-following stack takes a mesh, DEM or depth map");
  }
  if (!follows && !ground_plane) {
    UnitNormal(first_plane, "first_plane");
    UnitNormal(last_plane, "last_plane");
  }
}

bool FollowsSurface(const IntegralOptions& render) {
  return render.focal_surface.kind() != FocalSurfaceKind::kPlane;
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

std::vector<double> StackOffsets(double first_offset, double last_offset, int slices) {
  if (slices < 1) ThrowInvalid("slices: must be >= 1 (got " + std::to_string(slices) + ")");
  std::vector<double> offsets;
  offsets.reserve(static_cast<size_t>(slices));
  for (int i = 0; i < slices; ++i) {
    // first + (last - first) i / (N - 1), multiplied before dividing so that round offsets
    // stay round; the last is exactly last_offset.
    offsets.push_back(slices == 1 ? 0.5 * (first_offset + last_offset)
                      : i == slices - 1
                          ? last_offset
                          : first_offset + (last_offset - first_offset) * i / (slices - 1));
  }
  return offsets;
}

int SliceFocus::size() const {
  return static_cast<int>(surface ? offsets.size() : planes.size());
}

Plane SliceFocus::GrazingPlane() const {
  if (surface) return Plane{Vec3d(0.0), placement.up};
  if (planes.empty()) ThrowInvalid("focal stack: no slices");
  return planes.front();
}

Image SliceFocus::DepthOfSlices(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                                const std::vector<float>& slice, int threads) const {
  const int last = size() - 1;
  if (last < 0) ThrowInvalid("focal stack: no slices");
  const size_t pixels = static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height);
  if (slice.size() != pixels) ThrowInvalid("slice: one fractional index per pixel expected");
  if (surface) {
    // The offset is linear in the slice index, so a fractional slice's surface is the surface at
    // the interpolated offset: cast every pixel at its own offset.
    std::vector<double> pixel_offsets(pixels, 0.0);
    for (size_t i = 0; i < pixels; ++i) {
      const float z = slice[i];
      if (z < 0.0f) continue;
      const int i0 = std::min(static_cast<int>(z), last);
      const double fraction = z - i0;
      pixel_offsets[i] = i0 == last || fraction == 0.0
                             ? offsets[static_cast<size_t>(i0)]
                             : (1.0 - fraction) * offsets[static_cast<size_t>(i0)] +
                                   fraction * offsets[static_cast<size_t>(i0 + 1)];
    }
    Image depth =
        surface->DepthForOffsets(camera, cam_from_world, placement, pixel_offsets, threads);
    for (int y = 0; y < camera.height; ++y) {
      float* row = depth.At<float>(0, y);
      for (int x = 0; x < camera.width; ++x) {
        if (slice[static_cast<size_t>(y) * camera.width + x] < 0.0f) row[x] = 0.0f;
      }
    }
    return depth;
  }
  Image depth(camera.width, camera.height, 1, PixelType::kF32);
  const Vec3d center = cam_from_world.Center();
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t yy = 0; yy < camera.height; ++yy) {
    const int y = static_cast<int>(yy);
    float* row = depth.At<float>(0, y);
    for (int x = 0; x < camera.width; ++x) {
      const float z = slice[static_cast<size_t>(y) * camera.width + x];
      if (z < 0.0f) {
        row[x] = 0.0f;
        continue;
      }
      const int i0 = std::min(static_cast<int>(z), last);
      const double fraction = z - i0;
      const Plane plane = i0 == last || fraction == 0.0
                              ? planes[static_cast<size_t>(i0)]
                              : InterpolatePlane(planes[static_cast<size_t>(i0)],
                                                 planes[static_cast<size_t>(i0 + 1)], fraction, center);
      const Vec3d normal = glm::normalize(plane.normal);
      const Vec3d direction = world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double f = glm::dot(normal, direction);
      const double t = f != 0.0 ? glm::dot(normal, plane.point - center) / f : 0.0;
      row[x] = t > 0.0 && std::isfinite(t) ? static_cast<float>(t) : 0.0f;
    }
  }
  return depth;
}

SliceFocus ResolveSliceFocus(const LightField& light_field, const FocalStackOptions& options) {
  options.Check(static_cast<int>(light_field.views.size()));
  SliceFocus focus;
  if (FollowsSurface(options.render)) {
    focus.surface = std::make_shared<const FocalSurface>(options.render.focal_surface);
    focus.placement = ResolveSurfacePlacement(*focus.surface, light_field,
                                              options.render.view_indices, 0.0);
    focus.offsets = StackOffsets(options.first_offset, options.last_offset, options.slices);
  } else {
    Plane first = options.first_plane, last = options.last_plane;
    if (options.ground_plane) {
      // The ground's normal turned towards the views, the planes moved along it.
      const Vec3d point = options.ground_plane->point;
      Vec3d normal = glm::normalize(options.ground_plane->normal);
      Vec3d centres(0.0);
      int count = 0;
      for (size_t i = 0; i < light_field.views.size(); ++i) {
        const std::vector<int>& selected = options.render.view_indices;
        if (!selected.empty() &&
            std::find(selected.begin(), selected.end(), static_cast<int>(i)) == selected.end()) {
          continue;
        }
        const Vec3d centre = light_field.views[i].cam_from_world.Center();
        if (!std::isfinite(centre.x) || !std::isfinite(centre.y) || !std::isfinite(centre.z)) continue;
        centres += centre;
        ++count;
      }
      if (count > 0 && glm::dot(normal, centres / static_cast<double>(count) - point) < 0.0) {
        normal = -normal;
      }
      first = Plane{point + options.first_offset * normal, normal};
      last = Plane{point + options.last_offset * normal, normal};
    }
    const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, options.render);
    focus.planes = StackPlanes(first, last, options.slices, cam_from_world.Center());
  }
  return focus;
}

void FocalStack::Check(const std::string& where) const {
  const size_t n = static_cast<size_t>(focus.size());
  if (n == 0) ThrowInvalid(where + ": the stack has no slices");
  if (images.size() != n || counts.size() != n || (!variances.empty() && variances.size() != n)) {
    ThrowInvalid(where + ": slices, images, counts and variances differ in number");
  }
  if (focus.surface) {
    if (!focus.planes.empty()) ThrowInvalid(where + ": a terrain-following stack has no planes");
    focus.placement.Check();
  }
  for (size_t i = 0; i < n; ++i) {
    const std::string slice = where + ": slice " + std::to_string(i);
    if (focus.surface) {
      if (!std::isfinite(focus.offsets[i])) ThrowInvalid(slice + ": offset: must be finite");
    } else {
      const Plane& plane = focus.planes[i];
      for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(plane.point[k]) || !std::isfinite(plane.normal[k])) {
          ThrowInvalid(slice + ": plane: point and normal must be finite");
        }
      }
      if (!(glm::length(plane.normal) > 0.0)) {
        ThrowInvalid(slice + ": plane: normal must not be zero");
      }
    }
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
  const SliceFocus focus = ResolveSliceFocus(light_field, options);
  ProgressStart(progress, "focal stack", options.slices);
  IntegralOptions render = options.render;
  for (int i = 0; i < options.slices; ++i) {
    if (ProgressCancelled(progress)) throw Cancelled();
    if (focus.surface) {
      render.surface_offset = focus.offsets[static_cast<size_t>(i)];
    } else {
      render.focal_surface = FocalSurface::FromPlane(focus.planes[static_cast<size_t>(i)]);
    }
    IntegralResult slice;
    try {
      slice = RenderIntegral(light_field, render);
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("slice " + std::to_string(i) + ": " + error.what());
    }
    on_slice(i, slice);
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
  stack.focus = ResolveSliceFocus(light_field, options);
  RenderFocalStackSlices(
      light_field, options,
      [&](int, IntegralResult& slice) {
        stack.cam_from_world = slice.cam_from_world;
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

// A terrain-following stack's surface, written into the stack folder `dir` in world
// coordinates (a DEM as surface.tif with its CRS, a mesh or a depth map's focal points as
// surface.ply), and its "surface" entry of stack.json.
ojson WriteStackSurface(const fs::path& dir, const SliceFocus& focus) {
  const FocalSurface& surface = *focus.surface;
  ojson j;
  if (surface.kind() == FocalSurfaceKind::kHeightfield) {
    j["file"] = "surface.tif";
    WriteHeightfield((dir / "surface.tif").string(), surface.heightfield());
  } else if (surface.kind() == FocalSurfaceKind::kPlane) {
    j["plane"] = PlaneToJson(surface.plane());
  } else {
    j["file"] = "surface.ply";
    std::vector<Vec3d> vertices = surface.mesh().vertices;
    if (surface.kind() == FocalSurfaceKind::kDepthMap) {
      // A depth map's focal points are in the local frame: into world coordinates.
      for (Vec3d& vertex : vertices) vertex += focus.placement.origin;
    }
    WritePly((dir / "surface.ply").string(), vertices, surface.mesh().triangles);
  }
  j["kind"] = FocalSurfaceKindName(surface.kind());
  if (!surface.source().empty()) j["source"] = surface.source();
  j["origin"] = Vec3ToJson(focus.placement.origin);
  j["up"] = Vec3ToJson(focus.placement.up);
  return j;
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
  // The render options whole, in their JSON form (options_json.h), but the focus: the slices'
  // planes or surface are written below.
  IntegralOptions r = stack.render;
  r.focal_surface = IntegralOptions{}.focal_surface;
  ojson render = OptionsToJson(r);
  render.erase("focal_surface");
  j["render"] = std::move(render);
  if (stack.focus.surface) j["surface"] = WriteStackSurface(temp, stack.focus);
  ojson slices = ojson::array();
  for (int i = 0; i < stack.size(); ++i) {
    ojson slice;
    if (stack.focus.surface) {
      slice["offset"] = stack.focus.offsets[static_cast<size_t>(i)];
    } else {
      slice["plane"] = PlaneToJson(stack.focus.planes[static_cast<size_t>(i)]);
    }
    slice["image"] = SliceName("slice", i);
    slice["count"] = SliceName("count", i);
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
  RequireKnownKeys(j, {"format", "version", "camera", "cam_from_world", "render", "surface",
                       "slices"},
                   top);
  if (ReadJsonNumber(RequireMember(j, "version", top), top / "version") != 1) {
    (top / "version").Fail("must be 1");
  }
  FocalStack stack;
  const LensCamera camera = ReadCameraJson(RequireMember(j, "camera", top), top / "camera");
  if (!camera.IsPinhole()) {
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
    // IntegralOptions in its JSON form (options_json.h: unknown keys refused, a missing one
    // keeps its default: stacks written before a field was stored were rendered at it). Older
    // stacks stored fov_deg, aperture_radius, min_view_angle_deg, view_indices (and
    // lens_tolerance_px) only. The focus is the stack's own (the slices, "surface").
    for (const char* required : {"fov_deg", "aperture_radius", "min_view_angle_deg",
                                 "view_indices"}) {
      RequireMember(render, required, at);
    }
    if (render.contains("focal_surface")) {
      (at / "focal_surface").Fail("a stack's focus is its slices (and its 'surface' entry)");
    }
    OptionsFromJson(render, at, &stack.render);
    // The camera is the stack's (camera, cam_from_world above).
    stack.render.pose_view = -1;
    stack.render.width = stack.camera.width;
    stack.render.height = stack.camera.height;
    stack.render.cam_from_world = stack.cam_from_world;
  } else {
    stack.render.fov_deg = stack.camera.FovXDeg();
  }
  if (j.contains("surface")) {
    // A terrain-following stack: its surface file in the folder, its placement.
    const json& surface = j["surface"];
    const JsonPath at = top / "surface";
    if (!surface.is_object()) at.Fail("must be an object");
    RequireKnownKeys(surface, {"file", "plane", "kind", "source", "origin", "up"}, at);
    if (surface.contains("plane")) {
      stack.focus.surface = std::make_shared<const FocalSurface>(
          FocalSurface::FromPlane(ReadPlaneJson(surface["plane"], at / "plane")));
    } else {
      const json& name = RequireMember(surface, "file", at);
      if (!name.is_string()) (at / "file").Fail("must be a string, got " + DescribeJson(name));
      const std::string path = (base / name.get<std::string>()).string();
      stack.focus.surface = std::make_shared<const FocalSurface>(FocalSurface::Read(path));
    }
    stack.focus.placement.origin = ReadVec3Json(RequireMember(surface, "origin", at), at / "origin");
    stack.focus.placement.up = ReadVec3Json(RequireMember(surface, "up", at), at / "up");
    try {
      stack.focus.placement.Check();
    } catch (const std::invalid_argument& error) {
      at.Fail(error.what());
    }
  }
  const json& slices = RequireMember(j, "slices", top);
  if (!slices.is_array() || slices.empty()) (top / "slices").Fail("must be a non-empty array");
  bool has_variance = true;
  for (size_t i = 0; i < slices.size(); ++i) has_variance = has_variance && slices[i].contains("variance");
  stack.render.variance = has_variance;  // rendered with variance: its images are stored
  for (size_t i = 0; i < slices.size(); ++i) {
    const JsonPath at = top / "slices" / i;
    const json& slice = slices[i];
    RequireKnownKeys(slice, {"plane", "offset", "image", "count", "variance"}, at);
    if (stack.focus.surface) {
      if (slice.contains("plane")) (at / "plane").Fail("a terrain-following stack's slice has an offset, not a plane");
      stack.focus.offsets.push_back(
          ReadJsonNumber(RequireMember(slice, "offset", at), at / "offset"));
    } else {
      if (slice.contains("offset")) (at / "offset").Fail("a slice with an offset needs the stack's \"surface\"");
      stack.focus.planes.push_back(ReadPlaneJson(RequireMember(slice, "plane", at), at / "plane"));
    }
    // Each file is checked as it is read, so that errors name it (FocalStack::Check then finds
    // nothing more to say about sizes and types).
    std::string path;
    auto read = [&](const std::string& key, int channels, const char* what) {
      const json& name = RequireMember(slice, key.c_str(), at);
      if (!name.is_string()) (at / key).Fail("must be a string, got " + DescribeJson(name));
      path = (base / name.get<std::string>()).string();
      Image image;
      try {
        image = ReadImage(path);
      } catch (const std::invalid_argument& error) {
        // "stack.json: slices[3].image: stack/slice_0003.tif: not found": the file, and the
        // stack that names it.
        ThrowInvalid((at / key).Text() + ": " + error.what());
      }
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
