// Tests of the orthographic map camera (map.h): its grid against hand-computed figures, its render
// of a plane against the analytic texture and an independent projection of every view, tiling
// bit for bit, and the GeoTIFF writer's refusals and cleanliness.
#include "aos/render/map.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/util/error.h"
#include "plane_scene.h"
#include "render_test_util.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::GridCentres;
using test_util::NadirLightField;
using test_util::SameImage;

// A linear texture on the ground z = 0: bilinear sampling of point samples reproduces it exactly
// away from the views' outer half pixel.
SyntheticScene LinearGround() {
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d& p, float* value) {
    value[0] = static_cast<float>(100.0 + 3.0 * p.x + 2.0 * p.y);
    return true;
  }});
  return scene;
}

// 3 x 3 float views 2 m apart at 20 m, 96 x 80 pixels, 50 degrees (about 0.19 m per view pixel).
LightField GroundLightField() {
  return NadirLightField(LinearGround(), PinholeCamera::FromFov(96, 80, 50.0),
                         GridCentres(3, 2.0, 20.0), PixelType::kF32);
}

std::string ErrorOf(const std::function<void()>& run) {
  try {
    run();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

TEST(MapGrid, ExtentPixelSizeAndGeoTransform) {
  LightField light_field = GroundLightField();
  light_field.origin = Vec3d(500000.0, 5300000.0, 300.0);
  MapOptions options;
  options.pixel_size = 0.5;
  options.extent = {500000.0 - 10.0, 5300000.0 - 5.0, 500000.0 + 10.25, 5300000.0 + 5.0};
  const MapGrid grid = ResolveMapGrid(light_field, options);
  EXPECT_EQ(grid.width, 41);  // ceil(20.25 / 0.5): the last column reaches past XMAX
  EXPECT_EQ(grid.height, 20);
  const std::array<double, 6> transform = grid.GeoTransform();
  EXPECT_EQ(transform[0], 499990.0);
  EXPECT_EQ(transform[1], 0.5);
  EXPECT_EQ(transform[2], 0.0);
  EXPECT_EQ(transform[3], 5300005.0);
  EXPECT_EQ(transform[4], 0.0);
  EXPECT_EQ(transform[5], -0.5);
  EXPECT_EQ(grid.up_z, 1.0);
  // Pixel centres at +0.5, row 0 at the top (largest y).
  EXPECT_DOUBLE_EQ(grid.CenterX(0), 499990.25);
  EXPECT_DOUBLE_EQ(grid.CenterY(0), 5300004.75);
  // The focal points: local frame, relative to the map's centre, on the plane.
  const FocalPoints points = MapFocalPoints(grid, 0, 0, 2, 1);
  EXPECT_DOUBLE_EQ(points.reference.x + points.points[0].x, -9.75);
  EXPECT_DOUBLE_EQ(points.reference.y + points.points[0].y, 4.75);
  EXPECT_DOUBLE_EQ(points.reference.z + points.points[0].z, 0.0);
  EXPECT_DOUBLE_EQ(points.reference.x + points.points[1].x, -9.25);
  // A pixel count instead of a size.
  options.pixel_size = 0.0;
  options.width = 81;
  EXPECT_DOUBLE_EQ(ResolveMapGrid(light_field, options).pixel_size, 20.25 / 81);
}

TEST(MapGrid, DefaultExtentIsTheFootprintsWidenedToWholePixels) {
  // One nadir view at (1, 2, 20) through a 96 x 80, 50-degree pinhole: its footprint on z = 0
  // is 20 * tan(25 deg) to each side, 80/96 of that above and below.
  const PinholeCamera camera = PinholeCamera::FromFov(96, 80, 50.0);
  const LightField light_field =
      NadirLightField(LinearGround(), camera, {Vec3d(1.0, 2.0, 20.0)}, PixelType::kF32);
  MapOptions options;
  options.pixel_size = 0.25;
  const MapGrid grid = ResolveMapGrid(light_field, options);
  const double half_x = 20.0 * 48.0 / camera.fx, half_y = 20.0 * 40.0 / camera.fy;
  EXPECT_DOUBLE_EQ(grid.x_min, std::floor((1.0 - half_x) / 0.25) * 0.25);
  EXPECT_DOUBLE_EQ(grid.y_max, std::ceil((2.0 + half_y) / 0.25) * 0.25);
  EXPECT_EQ(grid.width, static_cast<int>(std::round(
                            (std::ceil((1.0 + half_x) / 0.25) * 0.25 - grid.x_min) / 0.25)));
  // The focal plane above the views: up is -z (as for a z-down frame).
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(40.0));
  options.extent = {-5.0, -5.0, 5.0, 5.0};
  EXPECT_EQ(ResolveMapGrid(light_field, options).up_z, -1.0);
}

TEST(MapGrid, MaxPixelsBoundsTheMapAndCanBeRaised) {
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.extent = {-10.0, -10.0, 10.0, 10.0};
  options.pixel_size = 0.01;  // 2000 x 2000 pixels
  options.max_pixels = 3'999'999;
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }),
              HasSubstr("makes 2000 x 2000 pixels, more than max_pixels 3999999"));
  options.max_pixels = 4'000'000;
  EXPECT_EQ(ResolveMapGrid(light_field, options).width, 2000);
  options.max_pixels = 3;
  EXPECT_THAT(ErrorOf([&] { options.Check(1); }), HasSubstr("max_pixels: must be in [4, "));
}

TEST(MapGrid, RefusesBadSizesNamingTheField) {
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.extent = {-10.0, -10.0, 10.0, 10.0};
  options.pixel_size = -1.0;
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }), HasSubstr("pixel_size:"));
  options.pixel_size = 0.0;
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }), HasSubstr("pixel_size:"));
  options.pixel_size = 1e-4;  // 2e5 x 2e5 pixels
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }),
              HasSubstr("pixel_size: 0.0001 m over the extent 20 x 20 m makes 200000 x 200000"));
  options.pixel_size = 50.0;  // one pixel
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }),
              HasSubstr("pixel_size: 50 m over the extent 20 x 20 m makes a map of 1 x 1 pixels"));
  options.pixel_size = 0.5;
  options.extent = {10.0, -10.0, -10.0, 10.0};
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }),
              HasSubstr("extent: XMAX must exceed XMIN"));
  options.extent = {-10.0, -10.0, 10.0};
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }), HasSubstr("extent:"));
  options.extent = {-10.0, -10.0, 10.0, 10.0};
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(20.0));  // the views' mean centre lies on the plane
  EXPECT_THAT(ErrorOf([&] { ResolveMapGrid(light_field, options); }), HasSubstr("focal_surface:"));
}

TEST(DistributedOptions, DefaultsPassAndBadValuesAreRefusedNamingTheField) {
  const DistributedOptions defaults;
  EXPECT_NO_THROW(defaults.Check());
  EXPECT_EQ(defaults.workers, 0);
  auto error = [](const std::function<void(DistributedOptions&)>& set) {
    DistributedOptions options;
    set(options);
    return ErrorOf([&] { options.Check(); });
  };
  EXPECT_THAT(error([](auto& o) { o.workers = -1; }), HasSubstr("workers: must be >= 0"));
  EXPECT_THAT(error([](auto& o) { o.workers = 2, o.scheduler = "tcp://127.0.0.1:1"; }),
              HasSubstr("workers/scheduler: exclude each other"));
  EXPECT_THAT(error([](auto& o) { o.cache_mb = -1.0; }), HasSubstr("cache_mb: must be >= 0 and finite, got -1"));
  EXPECT_THAT(error([](auto& o) { o.cache_mb = std::nan(""); }), HasSubstr("cache_mb:"));
  EXPECT_THAT(error([](auto& o) { o.share_mb = INFINITY; }), HasSubstr("share_mb:"));
  // Bytes given as MiB: 1 GiB in bytes would be a 1 PiB budget.
  EXPECT_THAT(error([](auto& o) { o.cache_mb = 1 << 30; }),
              HasSubstr("cache_mb: 1073741824 MiB is more than 16 TiB; the budget is in MiB"));
  EXPECT_THAT(error([](auto& o) { o.share_mb = 1 << 29; }), HasSubstr("share_mb:"));
  EXPECT_THAT(error([](auto& o) { o.dashboard = true; }), HasSubstr("dashboard: needs workers"));
  DistributedOptions local;
  local.workers = 2;
  local.dashboard = true;
  local.share_mb = 0.0;
  EXPECT_NO_THROW(local.Check());
  DistributedOptions remote;
  remote.scheduler = "tcp://10.0.0.5:8786";
  EXPECT_NO_THROW(remote.Check());
}

// The views that see world point X (a nadir pinhole each): projected inside the image.
int ViewsSeeing(const LightField& light_field, const Vec3d& point) {
  int seen = 0;
  for (const View& view : light_field.views) {
    const Vec3d in_cam = view.cam_from_world.rotation * point + view.cam_from_world.translation;
    const PinholeCamera camera = view.camera.Pinhole();
    const double u = camera.fx * in_cam.x / in_cam.z + camera.cx;
    const double v = camera.fy * in_cam.y / in_cam.z + camera.cy;
    seen += in_cam.z > 0 && u >= 0 && u <= camera.width && v >= 0 && v <= camera.height;
  }
  return seen;
}

TEST(MapRender, PlaneComesBackAsItsTextureWithTheViewsThatSeeIt) {
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.pixel_size = 0.3;
  options.extent = {-14.0, -12.0, 14.0, 12.0};  // wider than the footprints: some pixels unseen
  const MapResult map = RenderMap(light_field, options);
  const MapGrid& grid = map.summary.grid;
  ASSERT_EQ(map.image.width(), grid.width);
  int64_t checked = 0, uncovered = 0;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const Vec3d point(grid.CenterX(col), grid.CenterY(row), 0.0);
      const int expected_count = ViewsSeeing(light_field, point);
      ASSERT_EQ(*map.count.At<uint32_t>(col, row), static_cast<uint32_t>(expected_count))
          << "pixel " << col << ", " << row;
      if (expected_count == 0) {
        EXPECT_EQ(*map.image.At<float>(col, row), 0.0f);
        ++uncovered;
        continue;
      }
      // Exact for a linear texture, but for taps in a view's outer half pixel (edges
      // replicated): at most |gradient| * half a view pixel (sqrt(13) * 0.1 m = 0.37).
      const double truth = 100.0 + 3.0 * point.x + 2.0 * point.y;
      EXPECT_NEAR(*map.image.At<float>(col, row), truth, 0.37) << "pixel " << col << ", " << row;
      ++checked;
    }
  }
  EXPECT_GT(checked, 2000);
  EXPECT_GT(uncovered, 100);
  EXPECT_EQ(map.summary.uncovered_pixels, uncovered);
}

TEST(MapRender, ApertureKeepsOnlyViewsWithinTheHorizontalRadius) {
  const LightField light_field = GroundLightField();  // centres 2 m apart around (0, 0)
  MapOptions options;
  options.pixel_size = 0.5;
  options.extent = {-1.0, -1.0, 1.0, 1.0};
  options.aperture_radius = 2.5;  // pixel centres within 0.75 m of the origin
  const MapResult map = RenderMap(light_field, options);
  for (int row = 0; row < map.summary.grid.height; ++row) {
    for (int col = 0; col < map.summary.grid.width; ++col) {
      const double x = map.summary.grid.CenterX(col), y = map.summary.grid.CenterY(row);
      int expected = 0;
      for (const View& view : light_field.views) {
        const Vec3d c = view.cam_from_world.Center();
        expected += std::hypot(c.x - x, c.y - y) <= 2.5;
      }
      EXPECT_EQ(*map.count.At<uint32_t>(col, row), static_cast<uint32_t>(expected));
    }
  }
}

TEST(MapRender, ViewsUsedAreTheViewsThatContributeAnywhereUnitedOverTiles) {
  const LightField light_field = GroundLightField();  // centres 2 m apart around (0, 0)
  MapOptions options;
  options.pixel_size = 0.05;
  options.extent = {-2.4, -0.4, 0.4, 0.4};  // 56 x 16 pixels along the row of views y = 0
  options.aperture_radius = 0.0;  // each pixel takes the view nearest to its vertical line:
                                  // view 3 at (-2, 0) for x < -1, view 4 at (0, 0) beyond
  options.tile_size = 16;         // 4 tiles: 1 + 1 + 2 + 1 views, 2 over the map
  const MapResult map = RenderMap(light_field, options);
  EXPECT_EQ(map.summary.tiles, 4);
  EXPECT_EQ(map.summary.views_selected, 9);
  EXPECT_EQ(map.summary.views_used, 2);
  EXPECT_EQ(*map.count.At<uint32_t>(0, 0), 1u);
  options.view_indices = {4, 5, 8};  // of these only view 4 is nearest anywhere
  const MapResult some = RenderMap(light_field, options);
  EXPECT_EQ(some.summary.views_selected, 3);
  EXPECT_EQ(some.summary.views_used, 1);
  options.view_indices.clear();
  options.aperture_radius = std::numeric_limits<double>::infinity();
  EXPECT_EQ(RenderMap(light_field, options).summary.views_used, 9);
}

TEST(MapRender, LensToleranceReachesTheRendererAndIsValidated) {
  // Fisheye views (180 degrees): lens_tolerance_px 0 projects every sample exactly, the default
  // takes local homographies; the two maps agree within the tolerance times the texture's steps
  // (surface_integral.h) but not bit for bit, which shows the option reached the renderer.
  const LensCamera lens =
      LensFromFov(LensModel::kFisheye, 96, 80, 180.0, {0.01, -0.002, 0, 0, 0}, 0.0, "test");
  LightField light_field;
  const std::vector<Vec3d> centres = GridCentres(3, 2.0, 20.0);
  for (size_t i = 0; i < centres.size(); ++i) {
    Image image(lens.width, lens.height, 1, PixelType::kF32, 1);
    for (int y = 0; y < lens.height; ++y) {
      for (int x = 0; x < lens.width; ++x) {
        image.At<float>(x, y)[0] = static_cast<float>(100.0 + 50.0 * std::sin(0.3 * x + 0.2 * y + i));
      }
    }
    image.FillBorder();
    light_field.views.push_back(
        MakeView("v" + std::to_string(i), lens, NadirCamFromWorld(centres[i]), std::move(image)));
  }
  MapOptions options;
  options.extent = {-12.0, -12.0, 12.0, 12.0};
  options.pixel_size = 0.25;
  options.lens_tolerance_px = 0.0;
  const MapResult exact = RenderMap(light_field, options);
  options.lens_tolerance_px = 0.02;
  const MapResult fast = RenderMap(light_field, options);
  ASSERT_GT(exact.summary.samples, 0);
  double largest = 0.0;
  for (int y = 0; y < exact.image.height(); ++y) {
    for (int x = 0; x < exact.image.width(); ++x) {
      if (exact.count.At<uint32_t>(x, y)[0] == 0 ||
          exact.count.At<uint32_t>(x, y)[0] != fast.count.At<uint32_t>(x, y)[0]) {
        continue;
      }
      largest = std::max(largest, static_cast<double>(std::abs(exact.image.At<float>(x, y)[0] -
                                                               fast.image.At<float>(x, y)[0])));
    }
  }
  // Neighbouring samples differ by at most 50 (0.3 + 0.2) = 25: twice the tolerance times that
  // (the bound is checked at the quads' nodes), plus float rounding.
  EXPECT_LE(largest, 2.0 * 0.02 * 25.0 + 1e-3);
  EXPECT_GT(largest, 1e-4);
  options.lens_tolerance_px = 1.5;
  EXPECT_THAT(ErrorOf([&] { RenderMap(light_field, options); }), HasSubstr("lens_tolerance_px:"));
}

// The one focal-surface value (map.h): an offset moves a plane along up exactly as it moves the
// plane's height, and a tilted plane renders as the same plane given as a mesh (HeightsAt on a
// plane is exact; a mesh's hit is recomputed in double on its triangle, so they agree to float
// rounding of the focal heights).
TEST(MapRender, APlaneIsAFocalSurfaceLikeAnyOther) {
  const LightField light_field = GroundLightField();  // views at z = 20: up is +z
  MapOptions options;
  options.pixel_size = 0.3;
  options.extent = {-6.0, -5.0, 6.0, 5.0};
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(1.5));
  const MapResult raised = RenderMap(light_field, options);
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.5));
  options.surface_offset = 1.0;
  const MapResult moved = RenderMap(light_field, options);
  EXPECT_EQ(moved.summary.grid.focal_height, 1.5);
  EXPECT_TRUE(SameImage(moved.image, raised.image));
  EXPECT_TRUE(SameImage(moved.count, raised.count));

  options.surface_offset = 0.0;
  const Plane tilted{Vec3d(0.0, 0.0, 0.5), Vec3d(0.1, -0.05, 1.0)};
  options.focal_surface = FocalSurface::FromPlane(tilted);
  const MapResult plane = RenderMap(light_field, options);
  const auto z_at = [&](double x, double y) {
    return tilted.point.z - (tilted.normal.x * x + tilted.normal.y * y) / tilted.normal.z;
  };
  Mesh mesh;
  for (const auto& [x, y] : {std::pair{-50.0, -50.0}, {50.0, -50.0}, {50.0, 50.0}, {-50.0, 50.0}}) {
    mesh.vertices.push_back(Vec3d(x, y, z_at(x, y)));
  }
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  options.focal_surface = FocalSurface::FromMesh(mesh);
  const MapResult on_mesh = RenderMap(light_field, options);
  EXPECT_TRUE(SameImage(plane.count, on_mesh.count));
  EXPECT_LT(test_util::MaxAbsDifference(plane.image, on_mesh.image), 1e-3);
  // And it is another image than the horizontal plane through the same point.
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.5));
  EXPECT_GT(test_util::MaxAbsDifference(RenderMap(light_field, options).image, plane.image), 0.05);
}

TEST(MapRender, TilesChangeNoBit) {
  LightField light_field = GroundLightField();
  light_field.origin = Vec3d(600000.0, 5200000.0, 0.0);  // UTM-sized world coordinates
  MapOptions options;
  options.pixel_size = 0.17;
  options.tile_size = 4096;
  const MapResult whole = RenderMap(light_field, options);
  options.tile_size = 16;  // many tiles, ragged at the right and bottom
  const MapResult tiled = RenderMap(light_field, options);
  EXPECT_GT(tiled.summary.tiles, 20);
  EXPECT_EQ(whole.summary.tiles, 1);
  EXPECT_TRUE(SameImage(whole.image, tiled.image));
  EXPECT_TRUE(SameImage(whole.count, tiled.count));
}

// Windows rendered from only the views MapWindowViews keeps are RenderMap's pixels, bit for bit
// (what the distributed maps rely on), and the selection does leave views out: 3 x 3 views 8 m
// apart at 10 m, each seeing about 9.3 x 7.8 m, so most windows meet few of them.
TEST(MapWindow, WindowsFromTheirOwnViewsChangeNoBit) {
  LightField light_field = NadirLightField(LinearGround(), PinholeCamera::FromFov(96, 80, 50.0),
                                           GridCentres(3, 8.0, 10.0), PixelType::kF32);
  light_field.origin = Vec3d(600000.0, 5200000.0, 0.0);
  MapOptions options;
  options.pixel_size = 0.2;
  options.tile_size = 16;
  const MapResult whole = RenderMap(light_field, options);
  const MapGrid grid = ResolveMapGrid(light_field, options);
  int windows = 0, fewer = 0;
  for (int y0 = 0; y0 < grid.height; y0 += 23) {
    for (int x0 = 0; x0 < grid.width; x0 += 19) {
      const int w = std::min(19, grid.width - x0), h = std::min(23, grid.height - y0);
      const std::vector<int> views = MapWindowViews(light_field, grid, options, x0, y0, w, h);
      ASSERT_FALSE(views.empty());  // the default extent is the footprints: every window is seen
      ++windows;
      fewer += views.size() < light_field.views.size();
      const SurfaceIntegralResult window =
          RenderMapWindow(light_field, grid, options, x0, y0, w, h, views);
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          ASSERT_EQ(window.integral.count.At<uint32_t>(x, y)[0],
                    whole.count.At<uint32_t>(x0 + x, y0 + y)[0]);
          // Bit for bit, NaN-free: compare the float bits.
          ASSERT_EQ(std::memcmp(window.integral.image.At<float>(x, y),
                                whole.image.At<float>(x0 + x, y0 + y), sizeof(float)), 0)
              << "window " << x0 << "," << y0 << " pixel " << x << "," << y;
        }
      }
    }
  }
  EXPECT_GT(fewer, windows / 2);
  EXPECT_THAT(ErrorOf([&] { MapWindowViews(light_field, grid, options, grid.width - 2, 0, 3, 3); }),
              HasSubstr("window: "));
  EXPECT_THAT(ErrorOf([&] { RenderMapWindow(light_field, grid, options, 0, 0, 4, 4, {}); }),
              HasSubstr("views: empty"));
}

class MapWrite : public testing_util::TempFolderTest {
 protected:
  std::vector<std::string> Files() const {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
};

TEST_F(MapWrite, WritesOneFileAndRefusesWhatItShould) {
  LightField light_field = GroundLightField();
  light_field.crs = "EPSG:32633";
  MapOptions options;
  options.pixel_size = 0.08;
  const std::string path = Path("map.tif");
  const MapSummary summary = WriteMapGeoTiff(light_field, options, path);
  EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
  EXPECT_GT(std::filesystem::file_size(path), 1000u);
  EXPECT_GT(summary.grid.width, 256);  // larger than a block: overviews are made
  // An existing output without force; with force it is replaced.
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, path); }),
              HasSubstr("map.tif: exists"));
  WriteMapGeoTiff(light_field, options, path, MapWriteOptions{true});
  EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
  // A missing folder, a folder as output, a CRS GDAL does not know: nothing written.
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, Path("no/map.tif")); }),
              HasSubstr("does not exist"));
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, dir_.string()); }),
              HasSubstr("is a folder"));
  light_field.crs = "EPSG:999999";
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, Path("other.tif")); }),
              HasSubstr("crs: 'EPSG:999999'"));
  EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
}

TEST_F(MapWrite, WindowWriterLeavesNothingWithoutCommit) {
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.pixel_size = 0.1;
  const MapGrid grid = ResolveMapGrid(light_field, options);
  Image image(8, 8, 1, PixelType::kF32);
  Image count(8, 8, 1, PixelType::kU32);
  {
    MapGeoTiffWriter writer(grid, 1, "", Path("map.tif"));
    writer.Write(0, 0, image, count);
    EXPECT_THAT(ErrorOf([&] { writer.Write(grid.width - 4, 0, image, count); }),
                HasSubstr("map.tif: window"));
    EXPECT_THAT(ErrorOf([&] { writer.Write(0, 0, count, count); }), HasSubstr("float32 image"));
  }  // destroyed without Commit()
  EXPECT_TRUE(Files().empty());
  MapGeoTiffWriter writer(grid, 1, "", Path("map.tif"));
  writer.Write(8, 8, image, count);
  writer.Commit();
  EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
  EXPECT_THAT(ErrorOf([&] { writer.Commit(); }), HasSubstr("already committed"));
}

// At the start of the COG copy (the temporary GeoTIFF flushed), records the size of the
// temporary file(s) in the folder.
class MeasureTemporary : public ProgressSink {
 public:
  explicit MeasureTemporary(std::filesystem::path dir) : dir_(std::move(dir)) {}
  void Start(const std::string&, int64_t) override {
    for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
      if (entry.path().string().find(".tiles.tif") != std::string::npos) bytes += entry.file_size();
    }
  }
  void Advance(int64_t) override {}
  bool Cancelled() override { return false; }
  uint64_t bytes = 0;

 private:
  std::filesystem::path dir_;
};

TEST_F(MapWrite, DiskEstimateCoversTheTemporaryFileAndTheCog) {
  // The temporary GeoTIFF is uncompressed: once every window is written it holds the bands and
  // the count as float32 (ZSTD would shrink these ramps many times) and the overview levels.
  // MapWriteDiskBytes() is that plus half of it for the COG.
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.pixel_size = 0.02;
  const MapGrid grid = ResolveMapGrid(light_field, options);
  ASSERT_GT(grid.width, 512);  // two overview levels at least
  for (int channels : {1, 3}) {
    MapGeoTiffWriter writer(grid, channels, "", Path("map.tif"));
    for (int y0 = 0; y0 < grid.height; y0 += 512) {
      for (int x0 = 0; x0 < grid.width; x0 += 512) {
        const int w = std::min(512, grid.width - x0), h = std::min(512, grid.height - y0);
        Image image(w, h, channels, PixelType::kF32);
        Image count(w, h, 1, PixelType::kU32);
        for (int y = 0; y < h; ++y) {  // samples everywhere: no block is left out as empty
          for (int x = 0; x < w; ++x) {
            count.At<uint32_t>(x, y)[0] = 1 + (x + y) % 7;
            for (int c = 0; c < channels; ++c) image.At<float>(x, y)[c] = 0.25f * x + y + c;
          }
        }
        writer.Write(x0, y0, image, count);
      }
    }
    MeasureTemporary measure(dir_);
    writer.Commit(&measure);
    EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
    const uint64_t estimate = MapWriteDiskBytes(grid, channels);
    const uint64_t raw = static_cast<uint64_t>(grid.width) * grid.height * (channels + 1) * 4;
    ASSERT_GT(measure.bytes, raw) << channels;  // uncompressed, with its overviews
    // The temporary part alone (2/3 of the estimate) covers the temporary file: every block
    // whole, the overview levels included (they may still be in GDAL's cache when measured).
    EXPECT_GE(estimate * 2 / 3, measure.bytes) << channels;
    EXPECT_GE(estimate, measure.bytes + std::filesystem::file_size(Path("map.tif"))) << channels;
    // Not wildly over: the overview levels (a third of the base at most) may still be in GDAL's
    // cache when the copy starts, and the COG guess is half the temporary file.
    EXPECT_LE(estimate, measure.bytes * 5 / 2 + (2u << 20)) << channels;
    std::filesystem::remove(Path("map.tif"));
  }
}

TEST_F(MapWrite, RefusesToStartWithoutTheDiskSpaceNamingTheFolder) {
  // A grid that no disk holds (4e12 pixels: petabytes): refused before any file is created.
  MapGrid grid;
  grid.pixel_size = 0.01;
  grid.width = 2000000;
  grid.height = 2000000;
  const std::string error =
      ErrorOf([&] { MapGeoTiffWriter writer(grid, 1, "", Path("map.tif")); });
  EXPECT_THAT(error, HasSubstr(Path("map.tif") + ": its folder "));
  EXPECT_THAT(error, HasSubstr("free; writing this 2000000 x 2000000 map needs about"));
  EXPECT_TRUE(Files().empty());
}

// Stops after the first tile row.
class StopAfterFirstRow : public ProgressSink {
 public:
  void Start(const std::string&, int64_t) override {}
  void Advance(int64_t units) override { done_ += units; }
  bool Cancelled() override { return done_ > 0; }

 private:
  std::atomic<int64_t> done_{0};
};

TEST_F(MapWrite, CancelLeavesNoFile) {
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.pixel_size = 0.1;
  options.tile_size = 64;
  options.num_threads = 1;
  StopAfterFirstRow stop;
  EXPECT_THROW(WriteMapGeoTiff(light_field, options, Path("map.tif"), {}, &stop), Cancelled);
  EXPECT_TRUE(Files().empty());
}

TEST_F(MapWrite, ASurfaceThatCoversNoneOfTheMapIsRefusedAndLeavesNoFile) {
  // Before: a DEM beside the flight (or in another frame: a UTM DEM under a light field without
  // origin or CRS) wrote an all-nodata GeoTIFF and returned, where aos-render integral refuses.
  // The map now makes integral's check (CheckSurfaceCovers), naming the surface, its x/y box
  // beside the map's and, for a DEM with a CRS under a light field without one, that cause.
  const LightField light_field = GroundLightField();
  MapOptions options;
  options.pixel_size = 0.25;
  options.extent = {-4.0, -4.0, 4.0, 4.0};
  Heightfield dem;
  dem.width = dem.height = 8;
  dem.geotransform = {600000.0, 1.0, 0.0, 5200008.0, 0.0, -1.0};
  dem.heights.assign(64, 0.0f);
  dem.crs_wkt = "EPSG:32633";
  options.focal_surface = FocalSurface::FromHeightfield(dem, "utm.tif");
  const std::string path = Path("map.tif");
  const std::string message = ErrorOf([&] { WriteMapGeoTiff(light_field, options, path); });
  EXPECT_THAT(message, HasSubstr("utm.tif: no pixel is covered: the surface does not cover the "
                                 "map (or no view sees it); check its extent and CRS: it spans "
                                 "x 600000.5 .. 600007.5, y 5200000.5 .. 5200007.5 (world), the "
                                 "map x -4 .. 4, y -4 .. 4"));
  EXPECT_THAT(message, HasSubstr("the surface is in EPSG:32633 (WGS 84 / UTM zone 33N) but the light field has none"));
  EXPECT_THAT(ErrorOf([&] { RenderMap(light_field, options); }), HasSubstr("utm.tif: no pixel is covered"));
  EXPECT_TRUE(Files().empty());
  // A surface under the map that no selected view sees (its box holds pixel centres): refused
  // after the render, again with no file left.
  Mesh square;
  square.vertices = {{-30, -30, 0}, {30, -30, 0}, {30, 30, 0}, {-30, 30, 0}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  options.focal_surface = FocalSurface::FromMesh(square, "square.obj");
  options.extent = {40.0, 40.0, 44.0, 44.0};  // beyond the square: refused before rendering
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, path); }),
              HasSubstr("square.obj: no pixel is covered: the surface does not cover the map"));
  options.extent = {20.0, 20.0, 24.0, 24.0};  // on the square, 15 m beside every footprint
  EXPECT_THAT(ErrorOf([&] { WriteMapGeoTiff(light_field, options, path); }),
              HasSubstr("square.obj: no pixel is covered: the surface does not cover the map "
                        "(or no view sees it); check its extent and CRS"));
  EXPECT_TRUE(Files().empty());
  // Covering part of the map is a map.
  options.extent = {-4.0, -4.0, 4.0, 4.0};
  const MapSummary summary = WriteMapGeoTiff(light_field, options, path);
  EXPECT_LT(summary.uncovered_pixels, int64_t{summary.grid.width} * summary.grid.height);
  EXPECT_EQ(Files(), std::vector<std::string>{"map.tif"});
}

}  // namespace
}  // namespace aos
