#include "aos/render/map.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "aos/util/error.h"

namespace aos {
namespace {

std::string Num(double value) { return FormatNumber(value); }

std::vector<int> Selection(const LightField& light_field, const std::vector<int>& indices) {
  if (!indices.empty()) return indices;
  std::vector<int> all(light_field.views.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return all;
}

// A point on the border of a w x h image, going round it: edge 0 top, 1 right, 2 bottom, 3 left,
// t in [0, 1) along the edge.
Vec2d BorderPixel(int edge, double t, double w, double h) {
  switch (edge) {
    case 0: return Vec2d(t * w, 0.0);
    case 1: return Vec2d(w, t * h);
    case 2: return Vec2d(w - t * w, h);
    default: return Vec2d(0.0, h - t * h);
  }
}

// Casts view `view`'s image border onto the plane z = height (local frame), growing the box
// [lo, hi]; throws when a border ray does not meet the plane in front of the view (the footprint
// is unbounded: the view sees the horizon).
void GrowByFootprint(const View& view, int index, double height, double* lo, double* hi) {
  const Mat3d world_from_cam = glm::transpose(view.cam_from_world.rotation);
  const Vec3d center = view.cam_from_world.Center();
  const int steps = 16;  // points per edge: lens distortion bends the edges
  const double w = view.camera.width, h = view.camera.height;
  int valid = 0;
  for (int edge = 0; edge < 4; ++edge) {
    for (int k = 0; k < steps; ++k) {
      const double t = static_cast<double>(k) / steps;
      const Vec2d pixel = BorderPixel(edge, t, w, h);
      Vec3d ray;
      if (!view.camera.Unproject(pixel, &ray)) continue;  // outside a fisheye's valid field
      const Vec3d direction = world_from_cam * ray;
      const double s = direction.z != 0.0 ? (height - center.z) / direction.z : -1.0;
      if (!(s > 0.0) || !std::isfinite(s)) {
        // The plane behind the camera as it looks (above a camera looking down): no footprint
        // at all, the case of altitudes above the take-off point against a terrain's heights.
        const double look_z = world_from_cam[2].z;  // the camera's z axis in the world
        if (std::abs(look_z) > 0.5 && (height - center.z) * look_z <= 0.0) {
          ThrowInvalid("focal_surface: the focal plane z = " + FormatNumber(height) +
                       " (local frame) lies above view " + std::to_string(index) +
                       (view.name.empty() ? "" : " (" + view.name + ")") + " at z = " +
                       FormatNumber(center.z) + ", behind it as it looks: the surface is above "
                       "the cameras. Altitudes above the take-off point (relative) against a "
                       "terrain's heights? Import them with altitude_reference 'takeoff'");
        }
        ThrowInvalid("extent: view " + std::to_string(index) +
                     (view.name.empty() ? "" : " (" + view.name + ")") +
                     " sees above the horizon of the focal plane, so its footprint is unbounded; "
                     "give the extent");
      }
      const Vec3d point = center + s * direction;
      lo[0] = std::min(lo[0], point.x);
      lo[1] = std::min(lo[1], point.y);
      hi[0] = std::max(hi[0], point.x);
      hi[1] = std::max(hi[1], point.y);
      ++valid;
    }
  }
  if (valid == 0) {
    ThrowInvalid("extent: view " + std::to_string(index) + " has no valid border ray");
  }
}

// The map's world box {XMIN, YMIN, XMAX, YMAX} (pixel edges).
std::vector<double> MapExtent(const MapGrid& grid) {
  return {grid.x_min, grid.y_max - grid.height * grid.pixel_size,
          grid.x_min + grid.width * grid.pixel_size, grid.y_max};
}

// A progress sink for one tile: forwards advances and cancels to the map's sink, ignores the
// tile's own stage.
class TileProgress : public ProgressSink {
 public:
  explicit TileProgress(ProgressSink* outer) : outer_(outer) {}
  void Start(const std::string&, int64_t) override {}
  void Advance(int64_t units) override { ProgressAdvance(outer_, units); }
  bool Cancelled() override { return ProgressCancelled(outer_); }

 private:
  ProgressSink* outer_;
};

}  // namespace

void MapOptions::Check(int view_count) const {
  CheckFieldRanges(*this);  // the table's ranges (map.h)
  if (pixel_size == 0.0) {
    if (width == 0) ThrowInvalid("pixel_size: must be > 0 (or give the width in pixels)");
    if (width < 2) ThrowInvalid("width: must be >= 2 pixels (got " + std::to_string(width) + ")");
  }
  if (!extent.empty()) {
    if (extent.size() != 4) {
      ThrowInvalid("extent: expected 4 numbers XMIN YMIN XMAX YMAX (got " +
                   std::to_string(extent.size()) + ")");
    }
    for (double v : extent) {
      if (!std::isfinite(v)) ThrowInvalid("extent: values must be finite");
      if (const std::string problem = SurfaceCoordinateProblem(v); !problem.empty()) {
        ThrowInvalid("extent: " + problem);
      }
    }
    if (!(extent[2] > extent[0]) || !(extent[3] > extent[1])) {
      ThrowInvalid("extent: XMAX must exceed XMIN and YMAX exceed YMIN (got " + Num(extent[0]) +
                   " " + Num(extent[1]) + " " + Num(extent[2]) + " " + Num(extent[3]) + ")");
    }
  }
  if (const std::string problem = SurfaceCoordinateProblem(surface_offset); !problem.empty()) {
    ThrowInvalid("surface_offset: " + problem);
  }
  if (view_count <= 0) ThrowInvalid("light field: has no views");
  for (int index : view_indices) {
    if (index < 0 || index >= view_count) {
      ThrowInvalid("view_indices: " + std::to_string(index) + " is not a view (the light field has " +
                   std::to_string(view_count) + ")");
    }
  }
}

std::array<double, 6> MapGrid::GeoTransform() const {
  return {x_min, pixel_size, 0.0, y_max, 0.0, -pixel_size};
}

MapGrid ResolveMapGrid(const LightField& light_field, const MapOptions& options) {
  const int view_count = static_cast<int>(light_field.views.size());
  options.Check(view_count);
  const std::vector<int> selection = Selection(light_field, options.view_indices);
  MapGrid grid;
  grid.origin = light_field.origin;

  // Up: the z direction from the focal plane (or surface) towards the views' mean centre. A
  // horizontal plane takes the plane path (grid.surface null); a tilted plane, a mesh or a DEM
  // the surface path (FocalSurface::HeightsAt).
  const FocalSurface& surface = options.focal_surface;
  const bool horizontal_plane = surface.kind() == FocalSurfaceKind::kPlane &&
                                surface.plane().normal.x == 0.0 &&
                                surface.plane().normal.y == 0.0;
  double plane_z = 0.0;
  if (!horizontal_plane) {
    grid.surface = std::make_shared<const FocalSurface>(surface);
    grid.placement = ResolveSurfacePlacement(surface, light_field, options.view_indices,
                                             options.surface_offset);
    grid.up_z = grid.placement.up.z;
    // The default extent's plane and the points' reference height: through the surface's
    // reference point, offset.
    plane_z = surface.ReferencePoint(light_field.origin).z + grid.placement.offset * grid.up_z;
  } else {
    const double height = surface.plane().point.z;
    double mean_z = 0.0;
    for (int index : selection) {
      mean_z += light_field.views[static_cast<size_t>(index)].cam_from_world.Center().z;
    }
    mean_z /= static_cast<double>(selection.size());
    if (mean_z == height) {
      ThrowInvalid("focal_surface: the views' mean centre lies on the focal plane (z = " +
                   Num(mean_z) + "), so up is undefined");
    }
    grid.up_z = mean_z > height ? 1.0 : -1.0;
    plane_z = height + options.surface_offset * grid.up_z;
  }
  grid.focal_height = plane_z;

  // Extent in world x/y.
  double lo[2], hi[2];
  const bool given = !options.extent.empty();
  if (given) {
    lo[0] = options.extent[0];
    lo[1] = options.extent[1];
    hi[0] = options.extent[2];
    hi[1] = options.extent[3];
  } else {
    lo[0] = lo[1] = std::numeric_limits<double>::infinity();
    hi[0] = hi[1] = -std::numeric_limits<double>::infinity();
    try {
      for (int index : selection) {
        GrowByFootprint(light_field.views[static_cast<size_t>(index)], index, plane_z, lo, hi);
      }
    } catch (const std::invalid_argument&) {
      // A surface far beside the views (a UTM DEM under a light field in a local frame) may lie
      // above them, flipping up, so that no footprint meets its plane: say that, not "give the
      // extent". Its x/y box against the views' centres tells.
      if (grid.surface) {
        std::vector<double> centres{std::numeric_limits<double>::infinity(),
                                    std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity()};
        for (int index : selection) {
          const Vec3d c = light_field.views[static_cast<size_t>(index)].cam_from_world.Center() +
                          light_field.origin;
          centres = {std::min(centres[0], c.x), std::min(centres[1], c.y),
                     std::max(centres[2], c.x), std::max(centres[3], c.y)};
        }
        const std::array<double, 4> box = grid.surface->ExtentInWorld(light_field.origin);
        if (box[2] < centres[0] || box[0] > centres[2] || box[3] < centres[1] ||
            box[1] > centres[3]) {
          CheckSurfaceCovers(*grid.surface, light_field,
                             "the map (under the views' centres)", 1, 1, centres);
        }
      }
      throw;
    }
    for (int i = 0; i < 2; ++i) {
      lo[i] += light_field.origin[i];
      hi[i] += light_field.origin[i];
    }
  }
  const double extent_w = hi[0] - lo[0];
  double p = options.pixel_size;
  if (p == 0.0) p = extent_w / options.width;
  if (!(p > 0.0) || !std::isfinite(p)) {
    ThrowInvalid("extent: the footprints have no width (" + Num(extent_w) + " m)");
  }
  // Fewer than 2 pixels on a side is judged on the extent itself (widening it to whole pixels
  // would turn a pixel as large as the flight into a 2 x 2 map).
  const double raw_columns = std::ceil((hi[0] - lo[0]) / p * (1.0 - 1e-12));
  const double raw_rows = std::ceil((hi[1] - lo[1]) / p * (1.0 - 1e-12));
  const std::string size_field = options.pixel_size > 0.0 ? "pixel_size" : "width";
  if (raw_columns < 2 || raw_rows < 2) {
    ThrowInvalid(size_field + ": " + Num(p) + " m over the extent " + Num(hi[0] - lo[0]) + " x " +
                 Num(hi[1] - lo[1]) + " m makes a map of " + Num(raw_columns) + " x " +
                 Num(raw_rows) + " pixels; it needs at least 2 on each side");
  }
  if (!given && options.pixel_size > 0.0) {
    // Whole multiples of the pixel size, outwards: maps of one flight line up. (With a pixel
    // count the footprints' box is kept, so that the map has exactly that many columns.)
    lo[0] = std::floor(lo[0] / p) * p;
    lo[1] = std::floor(lo[1] / p) * p;
    hi[0] = std::ceil(hi[0] / p) * p;
    hi[1] = std::ceil(hi[1] / p) * p;
  }
  const double columns = std::ceil((hi[0] - lo[0]) / p * (1.0 - 1e-12));
  const double rows = std::ceil((hi[1] - lo[1]) / p * (1.0 - 1e-12));
  if (!(columns * rows <= static_cast<double>(options.max_pixels)) || columns > 1e7 ||
      rows > 1e7) {
    ThrowInvalid(size_field + ": " + Num(p) + " m over the extent " + Num(hi[0] - lo[0]) + " x " +
                 Num(hi[1] - lo[1]) + " m makes " + Num(columns) + " x " + Num(rows) +
                 " pixels, more than max_pixels " + std::to_string(options.max_pixels) +
                 (columns > 1e7 || rows > 1e7 ? " or 10^7 on a side" : "") +
                 " (check the units of the pixel size and the extent; raise max_pixels for a map "
                 "that large on purpose)");
  }
  grid.x_min = lo[0];
  grid.y_max = hi[1];
  grid.pixel_size = p;
  grid.width = static_cast<int>(columns);
  grid.height = static_cast<int>(rows);
  if (grid.surface) {
    // A pixel's vertical line meets the surface only where its centre lies in the surface's x/y
    // box: with no centre in it the map would be all nodata. Refused before anything is rendered.
    const std::array<double, 4> box = grid.surface->ExtentInWorld(light_field.origin);
    if (box[2] < grid.CenterX(0) || box[0] > grid.CenterX(grid.width - 1) ||
        box[3] < grid.CenterY(grid.height - 1) || box[1] > grid.CenterY(0)) {
      const int64_t pixels = static_cast<int64_t>(grid.width) * grid.height;
      CheckSurfaceCovers(*grid.surface, light_field, "the map", pixels, pixels, MapExtent(grid));
    }
  }
  return grid;
}

FocalPoints MapFocalPoints(const MapGrid& grid, int x0, int y0, int w, int h) {
  FocalPoints points;
  points.width = w;
  points.height = h;
  // One reference for every tile (the map's centre on the focal plane): a pixel's point then
  // depends only on its column and row, so tiling changes no bit.
  points.reference = Vec3d(grid.CenterX(grid.width / 2) - grid.origin.x,
                           grid.CenterY(grid.height / 2) - grid.origin.y, grid.focal_height);
  points.points.resize(static_cast<size_t>(w) * static_cast<size_t>(h));
  for (int row = 0; row < h; ++row) {
    const double y = grid.CenterY(y0 + row) - grid.origin.y - points.reference.y;
    for (int col = 0; col < w; ++col) {
      const double x = grid.CenterX(x0 + col) - grid.origin.x - points.reference.x;
      // The plane z = focal_height: 0 relative to the reference.
      points.points[static_cast<size_t>(row) * w + col] = Vec3d(x, y, 0.0);
    }
  }
  if (grid.surface) {
    // The surface's world z under each pixel centre (NaN where the vertical line misses it).
    std::vector<Vec2d> xy(points.points.size());
    for (int row = 0; row < h; ++row) {
      for (int col = 0; col < w; ++col) {
        xy[static_cast<size_t>(row) * w + col] = Vec2d(grid.CenterX(x0 + col), grid.CenterY(y0 + row));
      }
    }
    const std::vector<double> z = grid.surface->HeightsAt(xy, grid.placement);
    for (size_t i = 0; i < z.size(); ++i) {
      points.points[i].z = z[i] - grid.origin.z - points.reference.z;  // NaN stays NaN
    }
  }
  return points;
}

PointIntegralOptions MapPointOptions(const MapGrid& grid, const MapOptions& options) {
  PointIntegralOptions point;
  static_cast<ApertureOptions&>(point) = options;  // the aperture, whole
  point.aperture = PointIntegralOptions::Aperture::kCylinder;
  point.lens_axis = Vec3d(0.0, 0.0, grid.up_z);
  point.surface_normal = Vec3d(0.0, 0.0, grid.up_z);
  return point;
}

MapSummary RenderMapTiles(const LightField& light_field, const MapOptions& options,
                          const std::function<void(const MapTile&)>& consume,
                          ProgressSink* progress) {
  MapSummary summary;
  summary.grid = ResolveMapGrid(light_field, options);
  const MapGrid& grid = summary.grid;
  const PointIntegralOptions point = MapPointOptions(grid, options);
  const int tile = options.tile_size;
  const int tiles_x = (grid.width + tile - 1) / tile;
  const int tiles_y = (grid.height + tile - 1) / tile;
  // A unit per tile row rendered (RenderIntegralAtPoints advances one per row).
  ProgressStart(progress, "render map", static_cast<int64_t>(grid.height) * tiles_x);
  TileProgress tile_progress(progress);
  std::vector<uint8_t> used(light_field.views.size(), 0);  // by light-field index, over all tiles
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      if (ProgressCancelled(progress)) throw Cancelled();
      const int x0 = tx * tile, y0 = ty * tile;
      const int w = std::min(tile, grid.width - x0), h = std::min(tile, grid.height - y0);
      const FocalPoints points = MapFocalPoints(grid, x0, y0, w, h);
      SurfaceIntegralResult rendered =
          RenderIntegralAtPoints(light_field, points, point, {}, &tile_progress);
      DropThinPixels(options.min_view_count, &rendered.integral);
      summary.views_selected = rendered.integral.views_selected;
      for (int index : rendered.used_view_indices) used[static_cast<size_t>(index)] = 1;
      summary.samples += rendered.integral.samples;
      summary.uncovered_pixels += rendered.integral.uncovered_pixels;
      ++summary.tiles;
      consume(MapTile{x0, y0, &rendered.integral});
    }
  }
  for (uint8_t u : used) summary.views_used += u;
  // An all-nodata map on a surface is no map of the terrain (a DEM beside the flight or in
  // another frame): refused like aos-render integral's render (WriteMapGeoTiff then leaves no
  // file).
  CheckMapCovered(light_field, grid, summary.uncovered_pixels);
  return summary;
}

void CheckMapCovered(const LightField& light_field, const MapGrid& grid, int64_t uncovered_pixels) {
  if (grid.surface) {
    CheckSurfaceCovers(*grid.surface, light_field, "the map", uncovered_pixels,
                       static_cast<int64_t>(grid.width) * grid.height, MapExtent(grid));
  }
}

MapResult RenderMap(const LightField& light_field, const MapOptions& options,
                    ProgressSink* progress) {
  MapResult map;
  map.crs = light_field.crs;
  const MapGrid grid = ResolveMapGrid(light_field, options);
  map.summary = RenderMapTiles(
      light_field, options,
      [&](const MapTile& tile) {
        const Image& image = tile.result->image;
        const Image& count = tile.result->count;
        if (map.image.empty()) {
          map.image = Image(grid.width, grid.height, image.channels(), PixelType::kF32);
          map.count = Image(grid.width, grid.height, 1, PixelType::kU32);
        }
        const size_t image_row = static_cast<size_t>(image.width()) * image.channels() * sizeof(float);
        const size_t count_row = static_cast<size_t>(count.width()) * sizeof(uint32_t);
        for (int row = 0; row < image.height(); ++row) {
          std::memcpy(map.image.At<float>(tile.x0, tile.y0 + row), image.At<float>(0, row),
                      image_row);
          std::memcpy(map.count.At<uint32_t>(tile.x0, tile.y0 + row),
                      count.At<uint32_t>(0, row), count_row);
        }
      },
      progress);
  return map;
}

void DistributedOptions::Check() const {
  CheckFieldRanges(*this);  // the table's ranges (map.h)
  if (workers > 0 && !scheduler.empty()) {
    ThrowInvalid("workers/scheduler: exclude each other (the cluster of " + scheduler +
                 " has its own workers)");
  }
  // A budget in bytes given as MiB (the old Python spelling was bytes) reads as petabytes.
  constexpr double kMostMib = 1 << 24;  // 16 TiB
  for (const auto& [name, value] : {std::pair{"cache_mb", cache_mb}, {"share_mb", share_mb}}) {
    if (value > kMostMib) {
      ThrowInvalid(std::string(name) + ": " + Num(value) + " MiB is more than 16 TiB; the " +
                   "budget is in MiB, not bytes");
    }
  }
  if (dashboard && workers == 0) {
    ThrowInvalid("dashboard: needs workers >= 1 (only a local cluster's is served here; a "
                 "scheduler's cluster serves its own)");
  }
}

namespace {

void CheckWindow(const MapGrid& grid, int x0, int y0, int w, int h) {
  if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || static_cast<int64_t>(x0) + w > grid.width ||
      static_cast<int64_t>(y0) + h > grid.height) {
    ThrowInvalid("window: pixels " + std::to_string(x0) + "," + std::to_string(y0) + " " +
                 std::to_string(w) + "x" + std::to_string(h) + " are not inside the " +
                 std::to_string(grid.width) + "x" + std::to_string(grid.height) + " map");
  }
}

// The box, in normalised camera coordinates (x/z, y/z), that holds every point a lens model
// projects into its image: the image border (64 points per edge) cast back through the lens,
// widened by 2 % of its size. False when a border ray does not point forward (a fisheye wider
// than 180 degrees): no such box, the view is kept.
bool LensImageBox(const LensCamera& camera, double* lo, double* hi) {
  const int steps = 64;
  const double w = camera.width, h = camera.height;
  lo[0] = lo[1] = std::numeric_limits<double>::infinity();
  hi[0] = hi[1] = -std::numeric_limits<double>::infinity();
  for (int edge = 0; edge < 4; ++edge) {
    for (int k = 0; k < steps; ++k) {
      const double t = static_cast<double>(k) / steps;
      const Vec2d pixel = BorderPixel(edge, t, w, h);
      Vec3d ray;
      if (!camera.Unproject(pixel, &ray)) return false;
      if (!(ray.z > 1e-6)) return false;
      const double nx = ray.x / ray.z, ny = ray.y / ray.z;
      lo[0] = std::min(lo[0], nx);
      lo[1] = std::min(lo[1], ny);
      hi[0] = std::max(hi[0], nx);
      hi[1] = std::max(hi[1], ny);
    }
  }
  const double margin_x = 0.02 * (hi[0] - lo[0]), margin_y = 0.02 * (hi[1] - lo[1]);
  lo[0] -= margin_x;
  hi[0] += margin_x;
  lo[1] -= margin_y;
  hi[1] += margin_y;
  return std::isfinite(lo[0]) && std::isfinite(hi[0]) && std::isfinite(lo[1]) && std::isfinite(hi[1]);
}

}  // namespace

std::vector<int> MapWindowViews(const LightField& light_field, const MapGrid& grid,
                                const MapOptions& options, int x0, int y0, int w, int h) {
  options.Check(static_cast<int>(light_field.views.size()));
  CheckWindow(grid, x0, y0, w, h);
  std::vector<int> selection = Selection(light_field, options.view_indices);
  std::sort(selection.begin(), selection.end());
  // The box of the window's finite focal points, local frame.
  Vec3d lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  Vec3d reference;
  if (grid.surface) {
    const FocalPoints points = MapFocalPoints(grid, x0, y0, w, h);
    for (const Vec3d& point : points.points) {
      if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) continue;
      lo = glm::min(lo, point);
      hi = glm::max(hi, point);
    }
    reference = points.reference;
  } else {
    // On the plane a pixel's point is (x(col), y(row), 0), each coordinate monotonic in its
    // index: the box is that of the window's four corner pixels, the same doubles
    // MapFocalPoints gives them (without the window's w x h points: 6 ms a 512^2 tile).
    const FocalPoints corners = MapFocalPoints(grid, x0, y0, 1, 1);
    const FocalPoints far = MapFocalPoints(grid, x0 + w - 1, y0 + h - 1, 1, 1);
    lo = glm::min(corners.points[0], far.points[0]);
    hi = glm::max(corners.points[0], far.points[0]);
    reference = corners.reference;
  }
  std::vector<int> views;
  if (!(lo.x <= hi.x)) return views;  // no pixel meets the focal surface
  lo += reference;
  hi += reference;
  for (int index : selection) {
    const View& view = light_field.views[static_cast<size_t>(index)];
    const LensCamera& camera = view.camera;
    double box_lo[2], box_hi[2];  // normalised coordinates that reach the image
    const bool pinhole = camera.IsPinhole();
    if (pinhole) {
      // Pixel u in [-1, width + 1] <=> x/z in [(-1 - cx) / fx, (width + 1 - cx) / fx].
      box_lo[0] = (-1.0 - camera.cx) / camera.fx;
      box_hi[0] = (camera.width + 1.0 - camera.cx) / camera.fx;
      box_lo[1] = (-1.0 - camera.cy) / camera.fy;
      box_hi[1] = (camera.height + 1.0 - camera.cy) / camera.fy;
    } else if (!LensImageBox(camera, box_lo, box_hi)) {
      views.push_back(index);
      continue;
    }
    // The window's box projects inside the hull of its corners' projections (all in front).
    double n_lo[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
    double n_hi[2] = {-n_lo[0], -n_lo[1]};
    bool keep = false;
    for (int corner = 0; corner < 8 && !keep; ++corner) {
      const Vec3d point((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y,
                        (corner & 4) ? hi.z : lo.z);
      const Vec3d in_cam = view.cam_from_world * point;
      if (!(in_cam.z > 1e-9)) {
        keep = true;  // a corner behind the view: no bound, keep it
        break;
      }
      const double nx = in_cam.x / in_cam.z, ny = in_cam.y / in_cam.z;
      n_lo[0] = std::min(n_lo[0], nx);
      n_hi[0] = std::max(n_hi[0], nx);
      n_lo[1] = std::min(n_lo[1], ny);
      n_hi[1] = std::max(n_hi[1], ny);
    }
    if (!keep) {
      keep = n_hi[0] >= box_lo[0] && n_lo[0] <= box_hi[0] && n_hi[1] >= box_lo[1] &&
             n_lo[1] <= box_hi[1];
    }
    if (keep) views.push_back(index);
  }
  return views;
}

std::vector<std::vector<int>> MapWindowsViews(const LightField& light_field, const MapGrid& grid,
                                              const MapOptions& options,
                                              const std::vector<MapWindow>& windows) {
  std::vector<std::vector<int>> views;
  views.reserve(windows.size());
  for (const MapWindow& window : windows) {
    views.push_back(MapWindowViews(light_field, grid, options, window.x0, window.y0, window.w,
                                   window.h));
  }
  return views;
}

SurfaceIntegralResult RenderMapWindow(const LightField& light_field, const MapGrid& grid,
                                      const MapOptions& options, int x0, int y0, int w, int h,
                                      const std::vector<int>& views, ProgressSink* progress) {
  options.Check(static_cast<int>(light_field.views.size()));
  CheckWindow(grid, x0, y0, w, h);
  if (views.empty()) {
    ThrowInvalid("views: empty; a window needs at least one view (any selected view renders an "
                 "empty window right)");
  }
  if (!options.view_indices.empty()) {
    for (int index : views) {
      if (std::find(options.view_indices.begin(), options.view_indices.end(), index) ==
          options.view_indices.end()) {
        ThrowInvalid("views: view " + std::to_string(index) + " is not in view_indices");
      }
    }
  }
  PointIntegralOptions point = MapPointOptions(grid, options);
  point.view_indices = views;
  const FocalPoints points = MapFocalPoints(grid, x0, y0, w, h);
  SurfaceIntegralResult rendered = RenderIntegralAtPoints(light_field, points, point, {}, progress);
  DropThinPixels(options.min_view_count, &rendered.integral);
  return rendered;
}

}  // namespace aos
