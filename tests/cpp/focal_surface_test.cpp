// Focal surfaces beyond planes (render/focal_surface.h) and the mesh and height-field readers
// they are made of (geometry/mesh.h, geometry/heightfield.h).
#include "aos/render/focal_surface.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>

#include <cpl_string.h>
#include <gdal.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/geometry/geodesy.h"
#include "aos/render/integral.h"
#include "aos/render/surface_integral.h"
#include "error_of.h"
#include "render_test_util.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::ErrorOf;
using test_util::SameImage;

class MeshFiles : public testing_util::TempFolderTest {
 protected:
  std::string Write(const std::string& name, const std::string& bytes) {
    const std::string path = Path(name);
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }
};

// ---- Mesh ----

TEST_F(MeshFiles, ObjReadsEveryFaceFormNegativeIndicesAndFansPolygons) {
  const std::string path = Write("m.obj",
                                 "# comment\nmtllib x.mtl\no thing\n"
                                 "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\n"
                                 "vt 0 0\nvn 0 0 1\ns off\nusemtl m\n"
                                 "f 1 2 3\r\n"
                                 "f 1/1 3/1 4/1\n"
                                 "f 1/1/1 2/1/1 4/1/1\n"
                                 "f 1//1 2//1 3//1\n"
                                 "f -4 -3 -2 -1\n");
  const Mesh mesh = ReadMesh(path);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  EXPECT_EQ(mesh.vertices[2], Vec3d(1, 1, 0));
  ASSERT_EQ(mesh.triangles.size(), 6u);
  EXPECT_EQ(mesh.triangles[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(mesh.triangles[1], (std::array<int, 3>{0, 2, 3}));
  EXPECT_EQ(mesh.triangles[2], (std::array<int, 3>{0, 1, 3}));
  // The quad of negative indices is fanned from its first corner.
  EXPECT_EQ(mesh.triangles[4], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(mesh.triangles[5], (std::array<int, 3>{0, 2, 3}));
  EXPECT_EQ(mesh.dropped_triangles, 0);
}

std::string PlyHeader(const std::string& format, const std::string& vertex_type, int vertices,
                      int faces) {
  return "ply\nformat " + format + " 1.0\ncomment made by a test\nelement vertex " +
         std::to_string(vertices) + "\nproperty " + vertex_type + " x\nproperty " + vertex_type +
         " y\nproperty " + vertex_type + " z\nproperty uchar red\nelement face " +
         std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
}

template <typename T>
void Append(std::string& bytes, T value) {
  bytes.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

TEST_F(MeshFiles, PlyAsciiAndBinaryLittleEndianFloatAndDouble) {
  const std::string ascii = Write("a.ply", PlyHeader("ascii", "float", 4, 1) +
                                               "0 0 0 1\n2 0 0 1\n2 3 0.5 1\n0 3 0.5 1\n"
                                               "4 0 1 2 3\n");
  for (const std::string& type : {std::string("float"), std::string("double")}) {
    std::string bytes = PlyHeader("binary_little_endian", type, 4, 1);
    const double xyz[4][3] = {{0, 0, 0}, {2, 0, 0}, {2, 3, 0.5}, {0, 3, 0.5}};
    for (const auto& v : xyz) {
      for (double c : v) {
        if (type == "float") Append(bytes, static_cast<float>(c)); else Append(bytes, c);
      }
      Append(bytes, static_cast<uint8_t>(7));
    }
    Append(bytes, static_cast<uint8_t>(4));
    for (int32_t i : {0, 1, 2, 3}) Append(bytes, i);
    const Mesh binary = ReadMesh(Write("b_" + type + ".ply", bytes));
    const Mesh text = ReadMesh(ascii);
    ASSERT_EQ(binary.vertices.size(), 4u);
    EXPECT_EQ(binary.vertices, text.vertices);
    EXPECT_EQ(binary.triangles, text.triangles);
    EXPECT_EQ(binary.vertices[2], Vec3d(2, 3, 0.5));
    ASSERT_EQ(binary.triangles.size(), 2u);
    EXPECT_EQ(binary.triangles[1], (std::array<int, 3>{0, 2, 3}));
  }
}

TEST_F(MeshFiles, DegenerateTrianglesAreDroppedAndCounted) {
  // A repeated index, and three collinear vertices (zero area): 2 of 4 triangles dropped.
  const Mesh mesh = ReadMesh(Write("d.obj",
                                   "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                                   "f 1 2 3\nf 1 1 3\nf 1 2 4\nf 2 3 4\n"));
  EXPECT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.dropped_triangles, 2);
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("all.obj", "v 0 0 0\nv 1 0 0\nf 1 2 2\n")); }),
              HasSubstr("no triangles (all 1 were degenerate"));
}

TEST_F(MeshFiles, BadMeshesAreRefusedNamingFileLineAndField) {
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n")); }),
              HasSubstr("nan.obj: line 2: v: y is not finite"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("inf.obj", "v 0 0 inf\n")); }),
              HasSubstr("inf.obj: line 1: v: z is not finite"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")); }),
              HasSubstr("range.obj: line 4: f: corner 3: vertex index 4 is out of range"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("neg.obj", "v 0 0 0\nf -1 -2 -3\n")); }),
              HasSubstr("neg.obj: line 2: f: corner 2: vertex index -2 is out of range"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n")); }),
              HasSubstr("two.obj: line 3: f: a face needs at least 3 corners"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("empty.obj", "")); }),
              HasSubstr("empty.obj: the mesh has no vertices"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("points.obj", "v 0 0 0\n")); }),
              HasSubstr("points.obj: the mesh has no triangles"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("big.ply", PlyHeader("binary_big_endian", "float", 0, 0))); }),
              HasSubstr("big.ply: header line 2: format: 'binary_big_endian' is not supported"));
  EXPECT_THAT(ErrorOf([&] {
                ReadMesh(Write("nan.ply", PlyHeader("ascii", "float", 3, 1) +
                                              "0 0 0 1\n1 0 nan 1\n0 1 0 1\n3 0 1 2\n"));
              }),
              HasSubstr("nan.ply: element vertex 1: z is not finite"));
  EXPECT_THAT(ErrorOf([&] {
                ReadMesh(Write("range.ply", PlyHeader("ascii", "float", 3, 1) +
                                                "0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 3\n"));
              }),
              HasSubstr("range.ply: element face 0: vertex_indices: index 3 is out of range"));
  EXPECT_THAT(ErrorOf([&] {
                // Long enough for the header's counts (3 x 4 + 1 tokens of >= 2 bytes), but short.
                ReadMesh(Write("short.ply", PlyHeader("ascii", "float", 3, 1) +
                                                "0 0 0 1\n1.00000000000000000 0 0\n"));
              }),
              HasSubstr("short.ply: element vertex 1: red: the file ends early"));
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Path("missing.obj")); }), HasSubstr("missing.obj"));
}

// ---- Heightfield ----

Heightfield TiltedField(int width, int height, double pixel) {
  // z = 0.3 + 0.02 x - 0.01 y on a grid centred near the origin.
  Heightfield field;
  field.width = width;
  field.height = height;
  field.geotransform = {-0.5 * width * pixel, pixel, 0.0, 0.5 * height * pixel, 0.0, -pixel};
  field.heights.resize(static_cast<size_t>(width) * height);
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i < width; ++i) {
      field.heights[static_cast<size_t>(j) * width + i] =
          static_cast<float>(0.3 + 0.02 * field.CenterX(i) - 0.01 * field.CenterY(j));
    }
  }
  return field;
}

class HeightfieldFiles : public MeshFiles {};

TEST_F(HeightfieldFiles, WriteAndReadBackWithNodataAndWithoutCrs) {
  Heightfield field = TiltedField(5, 4, 2.0);
  field.heights[7] = std::numeric_limits<float>::quiet_NaN();
  const std::string path = Path("dem.tif");
  WriteHeightfield(path, field);
  const Heightfield back = ReadHeightfield(path);
  EXPECT_EQ(back.width, 5);
  EXPECT_EQ(back.height, 4);
  EXPECT_EQ(back.geotransform, field.geotransform);
  EXPECT_EQ(back.crs_wkt, "");  // no CRS: allowed, taken as the light field's world frame
  for (size_t i = 0; i < field.heights.size(); ++i) {
    if (i == 7) {
      EXPECT_TRUE(std::isnan(back.heights[i]));
    } else {
      EXPECT_EQ(back.heights[i], field.heights[i]) << i;
    }
  }
  EXPECT_THAT(ErrorOf([&] { WriteHeightfield(path, field); }), HasSubstr("dem.tif: the file exists"));
  WriteHeightfield(path, TiltedField(2, 2, 1.0), /*overwrite=*/true);
  EXPECT_EQ(ReadHeightfield(path).width, 2);
}

TEST_F(HeightfieldFiles, BadRastersAreRefusedNamingFileAndField) {
  Heightfield field = TiltedField(3, 3, 1.0);
  field.geotransform[2] = 0.1;
  EXPECT_THAT(ErrorOf([&] { WriteHeightfield(Path("rot.tif"), field); }),
              HasSubstr("rot.tif: geotransform: rotated or sheared"));
  EXPECT_FALSE(std::filesystem::exists(Path("rot.tif")));
  // A rotated GeoTIFF written by GDAL itself.
  GDALAllRegister();
  const std::string rotated = Path("rotated.tif");
  {
    GDALDatasetH dataset = GDALCreate(GDALGetDriverByName("GTiff"), rotated.c_str(), 3, 3, 1,
                                      GDT_Float32, nullptr);
    double gt[6] = {0, 1, 0.2, 0, 0.1, -1};
    GDALSetGeoTransform(dataset, gt);
    GDALClose(dataset);
  }
  EXPECT_THAT(ErrorOf([&] { ReadHeightfield(rotated); }),
              HasSubstr("rotated.tif: geotransform: rotated or sheared"));
  // Absurd size: a sparse 20000 x 20000 GeoTIFF (4e8 pixels > 2^28) takes a few bytes on disk.
  const std::string huge = Path("huge.tif");
  {
    char** options = nullptr;
    options = CSLSetNameValue(options, "SPARSE_OK", "TRUE");
    options = CSLSetNameValue(options, "TILED", "YES");
    GDALDatasetH dataset = GDALCreate(GDALGetDriverByName("GTiff"), huge.c_str(), 20000, 20000,
                                      1, GDT_Float32, options);
    CSLDestroy(options);
    double gt[6] = {0, 1, 0, 0, 0, -1};
    GDALSetGeoTransform(dataset, gt);
    GDALClose(dataset);
  }
  EXPECT_THAT(ErrorOf([&] { ReadHeightfield(huge); }),
              HasSubstr("huge.tif: size: 20000 x 20000 pixels is not 1 .. 268435456"));
  // Blocks the file does not hold (a sparse GeoTIFF, or size tags claiming more than was
  // written): GDAL reads them as heights of 0 without a nodata value (refused), as nodata with
  // one (holes).
  for (const bool nodata : {false, true}) {
    const std::string sparse = Path(nodata ? "sparse_nodata.tif" : "sparse.tif");
    char** options = nullptr;
    options = CSLSetNameValue(options, "SPARSE_OK", "TRUE");
    options = CSLSetNameValue(options, "TILED", "YES");
    GDALDatasetH dataset = GDALCreate(GDALGetDriverByName("GTiff"), sparse.c_str(), 512, 512, 1,
                                      GDT_Float32, options);
    CSLDestroy(options);
    double gt[6] = {0, 1, 0, 0, 0, -1};
    GDALSetGeoTransform(dataset, gt);
    if (nodata) GDALSetRasterNoDataValue(GDALGetRasterBand(dataset, 1), -9999.0);
    std::vector<float> block(256 * 256, 12.5f);  // one tile of four written
    GDALRasterIO(GDALGetRasterBand(dataset, 1), GF_Write, 0, 0, 256, 256, block.data(), 256, 256,
                 GDT_Float32, 0, 0);
    GDALClose(dataset);
    if (!nodata) {
      EXPECT_THAT(ErrorOf([&] { ReadHeightfield(sparse); }),
                  AllOf(HasSubstr("band 1: 75 % of the raster has no data in the file"),
                        HasSubstr("heights of 0")));
      continue;
    }
    const Heightfield holes = ReadHeightfield(sparse);
    EXPECT_EQ(holes.heights[0], 12.5f);                       // the written tile
    EXPECT_TRUE(std::isnan(holes.heights[511 * 512 + 511]));  // a missing one: a hole
  }
  // No geotransform at all.
  const std::string plain = Path("plain.tif");
  {
    GDALDatasetH dataset = GDALCreate(GDALGetDriverByName("GTiff"), plain.c_str(), 3, 3, 1,
                                      GDT_Float32, nullptr);
    GDALClose(dataset);
  }
  EXPECT_THAT(ErrorOf([&] { ReadHeightfield(plain); }),
              HasSubstr("plain.tif: geotransform: the raster has none"));
  // Every pixel nodata.
  Heightfield empty = TiltedField(3, 3, 1.0);
  for (float& h : empty.heights) h = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { WriteHeightfield(Path("nodata.tif"), empty); }),
              HasSubstr("nodata.tif: heights: every pixel is nodata"));
  EXPECT_THAT(ErrorOf([&] { ReadHeightfield(Path("missing.tif")); }), HasSubstr("missing.tif"));
  EXPECT_THAT(ErrorOf([&] { ReadHeightfield(Write("text.tif", "not a raster")); }),
              HasSubstr("text.tif: height field: GDAL cannot read it"));
}

TEST(HeightfieldToMesh, TwoTrianglesPerCompleteCellAtPixelCentres) {
  Heightfield field = TiltedField(4, 3, 1.0);
  Mesh mesh = HeightfieldToMesh(field);
  EXPECT_EQ(mesh.vertices.size(), 12u);
  EXPECT_EQ(mesh.triangles.size(), 2u * 3 * 2);
  EXPECT_EQ(mesh.vertices[0], Vec3d(-1.5, 1.0, field.heights[0]));
  field.heights[5] = std::numeric_limits<float>::quiet_NaN();  // pixel (1, 1): 4 cells lose it
  mesh = HeightfieldToMesh(field);
  EXPECT_EQ(mesh.triangles.size(), 2u * (6 - 4));
}

// ---- Focal surfaces on a synthetic light field ----

// 5 x 5 nadir views 3 m apart at 20 m over a smooth textured ground at z = 0.3.
const LightField& Ground() {
  static const LightField light_field = test_util::NadirLightField(
      test_util::TexturedGround(0.3), PinholeCamera::FromFov(96, 96, 50.0),
      test_util::GridCentres(5, 3.0, 20.0), PixelType::kU8);
  return light_field;
}

IntegralOptions GroundOptions() {
  IntegralOptions options;
  options.cam_from_world = LookAt(Vec3d(0.7, -0.4, 20), Vec3d(0, 1, 0), Vec3d(0, 1, 0));
  options.fov_deg = 60.0;
  options.width = 40;
  options.height = 30;
  options.num_threads = 1;
  return options;
}

// Two big triangles covering [-100, 100]^2 at z = height (world = local here).
Mesh SquareMesh(double height) {
  Mesh mesh;
  mesh.vertices = {{-100, -100, height}, {100, -100, height}, {100, 100, height}, {-100, 100, height}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

double MaxDifference(const Image& a, const Image& b) {
  double worst = 0.0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      worst = std::max(worst, std::abs(double(a.At<float>(x, y)[0]) - b.At<float>(x, y)[0]));
    }
  }
  return worst;
}

class SurfaceRender : public MeshFiles {};

TEST_F(SurfaceRender, AHorizontalPlaneAsMeshObjPlyDemAndDepthMapRendersAsThePlane) {
  // The reference is the homography render on z = 0.3. The other surfaces render per sample on
  // their depth maps, which equal the plane's to float32 rounding (the mesh's hit distance is
  // recomputed in double on the hit triangle). Per-sample and homography positions differ by
  // ~1e-5 px (merge_test's PlainMeanOnAPlanesDepth...: the texture's slope is <= ~60 grey per
  // view pixel), so values agree within 1e-3 grey and counts exactly.
  const LightField& light_field = Ground();
  IntegralOptions options = GroundOptions();
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.3));
  const IntegralResult plane = RenderIntegral(light_field, options);
  const PinholeCamera camera = VirtualCamera(light_field, options);
  const Image plane_depth = PlaneDepth(camera, options.cam_from_world, options.focal_surface.plane());

  const std::string obj = Write("square.obj",
                                "v -100 -100 0.3\nv 100 -100 0.3\nv 100 100 0.3\nv -100 100 0.3\n"
                                "f 1 2 3 4\n");
  const std::string ply = Write("square.ply", PlyHeader("ascii", "double", 4, 1) +
                                                  "-100 -100 0.3 0\n100 -100 0.3 0\n"
                                                  "100 100 0.3 0\n-100 100 0.3 0\n4 0 1 2 3\n");
  Heightfield dem;
  dem.width = dem.height = 2;
  dem.geotransform = {-200.0, 200.0, 0.0, 200.0, 0.0, -200.0};  // centres at +-100
  dem.heights.assign(4, 0.3f);
  WriteHeightfield(Path("square.tif"), dem);

  const std::vector<std::pair<std::string, FocalSurface>> surfaces = {
      {"mesh", FocalSurface::FromMesh(SquareMesh(0.3))},
      {"obj", FocalSurface::Read(obj)},
      {"ply", FocalSurface::Read(ply)},
      {"dem", FocalSurface::Read(Path("square.tif"))},
      {"depth", FocalSurface::FromDepthMap(plane_depth, camera, options.cam_from_world)},
      {"plane", FocalSurface::FromPlane(Plane::AtHeight(0.3))}};
  EXPECT_EQ(surfaces[3].second.kind(), FocalSurfaceKind::kHeightfield);
  for (const auto& [name, surface] : surfaces) {
    SCOPED_TRACE(name);
    const SurfacePlacement placement = ResolveSurfacePlacement(surface, light_field, {}, 0.0);
    EXPECT_EQ(placement.up, Vec3d(0, 0, 1));
    const Image depth = surface.DepthFor(camera, options.cam_from_world, placement);
    double worst_relative = 0.0;
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const double a = depth.At<float>(x, y)[0], b = plane_depth.At<float>(x, y)[0];
        worst_relative = std::max(worst_relative, std::abs(a - b) / b);
      }
    }
    EXPECT_LE(worst_relative, 1.2e-7);  // one float32 rounding (2^-23) of the depth
    IntegralOptions surface_options = options;
    surface_options.focal_surface = surface;
    const IntegralResult result = RenderIntegral(light_field, surface_options);
    EXPECT_TRUE(SameImage(result.count, plane.count));
    EXPECT_LT(MaxDifference(result.image, plane.image), 1e-3);
    EXPECT_EQ(result.uncovered_pixels, plane.uncovered_pixels);
    EXPECT_EQ(result.samples, plane.samples);
    EXPECT_GT(result.samples, 0);
  }
}

TEST(SurfaceOffset, AMeshAtHeightHWithOffsetDIsThePlaneAtHPlusDUp) {
  const LightField& light_field = Ground();
  IntegralOptions options = GroundOptions();
  options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.3 + 0.45));
  const IntegralResult plane = RenderIntegral(light_field, options);
  IntegralOptions mesh_options = GroundOptions();
  mesh_options.focal_surface = FocalSurface::FromMesh(SquareMesh(0.3));
  mesh_options.surface_offset = 0.45;  // up is +z here: views at z = 20 above the mesh
  const IntegralResult mesh = RenderIntegral(light_field, mesh_options);
  EXPECT_TRUE(SameImage(mesh.count, plane.count));
  EXPECT_LT(MaxDifference(mesh.image, plane.image), 1e-3);
  // Without the offset it is another image (the focus moved 0.45 m).
  mesh_options.surface_offset = 0.0;
  EXPECT_GT(MaxDifference(RenderIntegral(light_field, mesh_options).image, plane.image), 1.0);
  // A plane surface with an offset equals the moved focal_plane exactly (the same kernel).
  IntegralOptions plane_surface = GroundOptions();
  plane_surface.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.3));
  plane_surface.surface_offset = 0.45;
  EXPECT_TRUE(SameImage(RenderIntegral(light_field, plane_surface).image, plane.image));
}

TEST(SurfacePlacement, UpPointsFromTheSurfaceTowardsTheViewsAndOffsetsFollowIt) {
  // Views above (z up) and below (z down, as JKU/F0 poses) a mesh at z = 5.
  const FocalSurface surface = FocalSurface::FromMesh(SquareMesh(5.0));
  LightField above, below;
  above.views.push_back(MakeView("a", PinholeCamera::FromFov(8, 8, 50.0), NadirCamFromWorld(Vec3d(0, 0, 30)), Image(8, 8, 1, PixelType::kU8)));
  below.views.push_back(MakeView("b", PinholeCamera::FromFov(8, 8, 50.0), NadirCamFromWorld(Vec3d(0, 0, -30)), Image(8, 8, 1, PixelType::kU8)));
  const SurfacePlacement up = ResolveSurfacePlacement(surface, above, {}, 2.0);
  const SurfacePlacement down = ResolveSurfacePlacement(surface, below, {}, 2.0);
  EXPECT_EQ(up.up, Vec3d(0, 0, 1));
  EXPECT_EQ(down.up, Vec3d(0, 0, -1));
  const std::vector<double> z_up = surface.HeightsAt({{1.0, 2.0}, {500.0, 0.0}}, up);
  const std::vector<double> z_down = surface.HeightsAt({{1.0, 2.0}}, down);
  EXPECT_DOUBLE_EQ(z_up[0], 7.0);
  EXPECT_TRUE(std::isnan(z_up[1]));  // outside the mesh: a miss
  EXPECT_DOUBLE_EQ(z_down[0], 3.0);
  // The light field's origin moves world meshes into the local frame.
  above.origin = Vec3d(1000.0, 2000.0, 4.0);
  const SurfacePlacement shifted = ResolveSurfacePlacement(surface, above, {}, 0.0);
  const Image depth = surface.DepthFor(PinholeCamera::FromFov(8, 8, 50.0), NadirCamFromWorld(Vec3d(-1000, -2000, 30)), shifted);
  EXPECT_FLOAT_EQ(depth.At<float>(3, 3)[0], 30.0f - (5.0f - 4.0f));
}

TEST(SurfaceBehind, ASurfaceAboveTheCamerasAsTheyLookIsNamedWithBothHeights) {
  // Nadir views at z = 30 (z up) and, as JKU's F0, views at z = -30 looking along +z (z down).
  const PinholeCamera camera = PinholeCamera::FromFov(8, 8, 50.0);
  LightField up, down;
  up.views.push_back(MakeView("a", camera, NadirCamFromWorld(Vec3d(0, 0, 30)), Image(8, 8, 1, PixelType::kU8)));
  Rigid3d looking_along_z;  // identity rotation: the camera's z axis is the world's +z
  looking_along_z.translation = Vec3d(0, 0, 30);  // centre (0, 0, -30)
  down.views.push_back(MakeView("b", camera, looking_along_z, Image(8, 8, 1, PixelType::kU8)));
  // Relative altitudes (30 m) against a terrain 300 m above sea level: behind every camera.
  const FocalSurface terrain = FocalSurface::FromMesh(SquareMesh(300.0), "dem.tif");
  EXPECT_THAT(SurfaceBehindTheCameras(terrain, up),
              HasSubstr("the surface lies above the cameras (behind them, as they look): its "
                        "world z is 300 and the cameras' 30"));
  EXPECT_EQ(SurfaceBehindTheCameras(FocalSurface::FromMesh(SquareMesh(5.0)), up), "");
  EXPECT_EQ(SurfaceBehindTheCameras(FocalSurface::FromPlane(Plane::AtHeight(29.0)), up), "");
  EXPECT_THAT(SurfaceBehindTheCameras(FocalSurface::FromPlane(Plane::AtHeight(31.0)), up),
              HasSubstr("world z is 31 and the cameras' 30"));
  // z down: "above" is the smaller z.
  EXPECT_EQ(SurfaceBehindTheCameras(FocalSurface::FromMesh(SquareMesh(21.0)), down), "");
  EXPECT_THAT(SurfaceBehindTheCameras(FocalSurface::FromMesh(SquareMesh(-40.0)), down),
              HasSubstr("(z pointing down)"));
  // The render covers nothing, and the one check says why.
  IntegralOptions options;
  options.pose_view = 0;
  options.focal_surface = terrain;
  const IntegralResult result = RenderIntegral(up, options);
  const int64_t pixels = int64_t{result.image.width()} * result.image.height();
  ASSERT_EQ(result.uncovered_pixels, pixels);
  EXPECT_THAT(ErrorOf([&] {
                CheckSurfaceCovers(terrain, up, "the view", result.uncovered_pixels, pixels);
              }),
              HasSubstr("dem.tif: no pixel is covered: the surface lies above the cameras"));
}

TEST(SurfaceCrs, ADemInAnotherCrsIsRefusedNamingBothAndMovedByInCrs) {
  // A DEM in UTM 33N under a light field in UTM 32N (the same place: 15 E is zone 32's edge).
  LightField light_field;
  light_field.crs = "EPSG:32632";
  light_field.origin = Vec3d(0.0);
  const Vec3d centre = TransformPoints({Vec3d(500000.0, 5318000.0, 0.0)}, "EPSG:32633",
                                       "EPSG:32632", "t")[0];
  light_field.views.push_back(MakeView("a", PinholeCamera::FromFov(8, 8, 50.0),
                                       NadirCamFromWorld(centre + Vec3d(0, 0, 100)),
                                       Image(8, 8, 1, PixelType::kU8)));
  Heightfield dem;
  dem.width = dem.height = 4;
  dem.geotransform = {499980.0, 10.0, 0.0, 5318020.0, 0.0, -10.0};
  dem.heights.assign(16, 7.0f);
  dem.crs_wkt = "EPSG:32633";
  const FocalSurface surface = FocalSurface::FromHeightfield(dem, "dem.tif");
  EXPECT_THAT(ErrorOf([&] { ResolveSurfacePlacement(surface, light_field, {}, 0.0); }),
              HasSubstr("focal_surface: dem.tif is in EPSG:32633 (WGS 84 / UTM zone 33N) but the "
                        "light field is in EPSG:32632 (WGS 84 / UTM zone 32N)"));
  const FocalSurface moved = InCrs(surface, light_field.crs);
  const std::vector<double> z = moved.HeightsAt(
      {Vec2d(centre.x, centre.y)}, ResolveSurfacePlacement(moved, light_field, {}, 0.0));
  EXPECT_NEAR(z[0], 7.0, 1e-6);
}

TEST(SurfaceHeights, AHeightFieldOfAPlaneGivesThePlaneBetweenItsPixels) {
  // Linear interpolation over the triangles reproduces a plane exactly (up to the float32
  // heights: ~1e-7 relative of ~1 m).
  const Heightfield field = TiltedField(6, 5, 2.0);
  const FocalSurface surface = FocalSurface::FromHeightfield(field);
  SurfacePlacement placement;
  const std::vector<Vec2d> points = {{0.1, 0.2}, {-3.9, 2.7}, {4.2, -2.9}, {-100.0, 0.0}};
  const std::vector<double> z = surface.HeightsAt(points, placement);
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    EXPECT_NEAR(z[i], 0.3 + 0.02 * points[i].x - 0.01 * points[i].y, 1e-6) << i;
  }
  EXPECT_TRUE(std::isnan(z.back()));
}

// The nearest hit of a ray on a mesh by brute force, in double (Moller-Trumbore over every
// triangle): the reference for DepthFor's packets. Returns the distance t along `direction`, or
// NaN for a miss.
double BruteForceHit(const Mesh& mesh, const Vec3d& origin, const Vec3d& direction) {
  double best = std::numeric_limits<double>::quiet_NaN();
  for (const auto& triangle : mesh.triangles) {
    const Vec3d a = mesh.vertices[static_cast<size_t>(triangle[0])];
    const Vec3d e1 = mesh.vertices[static_cast<size_t>(triangle[1])] - a;
    const Vec3d e2 = mesh.vertices[static_cast<size_t>(triangle[2])] - a;
    const Vec3d p = glm::cross(direction, e2);
    const double det = glm::dot(e1, p);
    if (det == 0.0) continue;
    const Vec3d s = origin - a;
    const double u = glm::dot(s, p) / det;
    const Vec3d q = glm::cross(s, e1);
    const double v = glm::dot(direction, q) / det;
    const double t = glm::dot(e2, q) / det;
    if (u < 0.0 || v < 0.0 || u + v > 1.0 || !(t > 0.0)) continue;
    if (!(t >= best)) best = t;
  }
  return best;
}

TEST(SurfaceDepth, PacketCastGivesEveryPixelTheNearestHitOfABruteForceCast) {
  // A bumpy 12 x 12 m grid 20 m below the camera and, above part of it, a smaller tilted patch
  // (so the first hit matters); 37 x 23 pixels: rows end in a partial packet. Embree finds each
  // ray's triangle in float and DepthFor recomputes the distance on that triangle's plane in
  // double: the depth is the brute force's to the float rounding of the map (2^-24 relative),
  // except where a ray passes within Embree's float rounding of an edge and takes the
  // neighbouring triangle (the depths then differ by the crease times about 1e-6 m): 1e-5
  // relative covers both. Hit or miss must agree (no pixel here lies on the outline).
  Mesh mesh;
  const int n = 13;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = -6.0 + i, y = -6.0 + j;
      mesh.vertices.push_back(Vec3d(x, y, 0.4 * std::sin(1.3 * x) * std::cos(0.9 * y)));
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      mesh.triangles.push_back({a, a + 1, a + n + 1});
      mesh.triangles.push_back({a, a + n + 1, a + n});
    }
  }
  const int base = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(Vec3d(-1.0, -2.0, 3.0));
  mesh.vertices.push_back(Vec3d(3.0, -1.5, 2.0));
  mesh.vertices.push_back(Vec3d(0.5, 3.0, 4.0));
  mesh.triangles.push_back({base, base + 1, base + 2});
  const FocalSurface surface = FocalSurface::FromMesh(mesh);
  const PinholeCamera camera = PinholeCamera::FromFov(37, 23, 40.0);
  const Rigid3d cam_from_world = LookAt(Vec3d(0.7, -0.4, 20.0), Vec3d(0.2, 0.3, 0.0));
  SurfacePlacement placement;  // origin 0: the mesh is in the local frame
  const Image depth = surface.DepthFor(camera, cam_from_world, placement);
  const Vec3d centre = cam_from_world.Center();
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
  int hits = 0, upper_patch = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Vec3d direction = world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double t = BruteForceHit(mesh, centre, direction);
      const double got = depth.At<float>(x, y)[0];
      if (std::isnan(t)) {
        EXPECT_EQ(got, 0.0) << x << "," << y;
        continue;
      }
      ++hits;
      upper_patch += centre.z + t * direction.z > 1.0;
      EXPECT_NEAR(got, t, 1e-5 * t) << x << "," << y;
    }
  }
  EXPECT_GT(hits, camera.width * camera.height / 2);
  EXPECT_GT(upper_patch, 20);  // the upper patch is in view and occludes the grid
}

TEST(SurfaceMisses, PixelsWhoseRaysMissTheSurfaceGetCountZeroAndAreReported) {
  // A 4 m x 4 m square and a DEM with a nodata hole: rays beyond the square, or through the
  // hole's cells, miss and get count 0.
  const LightField& light_field = Ground();
  IntegralOptions options = GroundOptions();
  Mesh small;
  small.vertices = {{-2, -2, 0.3}, {2, -2, 0.3}, {2, 2, 0.3}, {-2, 2, 0.3}};
  small.triangles = {{0, 1, 2}, {0, 2, 3}};
  options.focal_surface = FocalSurface::FromMesh(small);
  const IntegralResult result = RenderIntegral(light_field, options);
  const PinholeCamera camera = VirtualCamera(light_field, options);
  const Image depth = options.focal_surface.DepthFor(
      camera, options.cam_from_world, ResolveSurfacePlacement(options.focal_surface, light_field, {}, 0.0));
  int64_t misses = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const bool miss = depth.At<float>(x, y)[0] == 0.0f;
      misses += miss;
      if (miss) EXPECT_EQ(result.count.At<uint32_t>(x, y)[0], 0u);
    }
  }
  EXPECT_GT(misses, 0);
  EXPECT_LT(misses, int64_t{camera.width} * camera.height);
  EXPECT_EQ(result.uncovered_pixels, misses);

  Heightfield dem = TiltedField(41, 41, 0.5);
  for (float& h : dem.heights) h = 0.3f;
  dem.heights[20 * 41 + 20] = std::numeric_limits<float>::quiet_NaN();  // the centre pixel
  options.focal_surface = FocalSurface::FromHeightfield(dem);
  const IntegralResult holed = RenderIntegral(light_field, options);
  EXPECT_GT(holed.uncovered_pixels, 0);
  EXPECT_LT(holed.uncovered_pixels, misses);
}

// ---- Coordinates the float ray cast cannot hold, and header sizes (issue 31) ----

// The values a broken file brings: past float (1e300: doubles only), at float's edge (3e38),
// beyond Embree's FLT_LARGE (1e20), beyond kMaxSurfaceCoordinate yet modest (5e9), not finite.
const double kExtremes[] = {1e20, 3e38, -3e38, 1e300, 5e9,
                            std::numeric_limits<double>::quiet_NaN(),
                            std::numeric_limits<double>::infinity()};

std::string Text(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

// A binary PLY of a 1 m square at z = 0 (double x, y, z) whose vertex 2 has z = `z`.
std::string BinaryPlySquare(double z) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
      "property double y\nproperty double z\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  const double xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, z}, {0, 1, 0}};
  for (const auto& v : xyz) {
    for (double c : v) Append(bytes, c);
  }
  Append(bytes, uint8_t{4});
  for (int i = 0; i < 4; ++i) Append(bytes, int32_t{i});
  return bytes;
}

// A binary PLY whose header declares `vertices` float vertices and `faces` faces, with `body`
// bytes after it.
std::string PlyWithCounts(const std::string& format, int64_t vertices, int64_t faces,
                          const std::string& body) {
  return "ply\nformat " + format + " 1.0\nelement vertex " + std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(faces) + "\nproperty list uchar int vertex_indices\nend_header\n" + body;
}

TEST_F(MeshFiles, ExtremeCoordinatesAreRefusedNamingFileVertexAndField) {
  // Before: a square at z = 1e20 read, and ray casting it aborted the process in Embree
  // (assert ray.valid(), exit 134). Every reader refuses such a vertex, naming where it is.
  for (double z : kExtremes) {
    SCOPED_TRACE(Text(z));
    const std::string obj = Write("e.obj", "v 0 0 0\nv 1 0 0\nv 1 1 " + Text(z) + "\nf 1 2 3\n");
    const std::string finite = std::isfinite(z) ? "beyond +-1000000000 m" : "is not finite";
    EXPECT_THAT(ErrorOf([&] { ReadMesh(obj); }), HasSubstr("e.obj: line 3: v: z "));
    EXPECT_THAT(ErrorOf([&] { ReadMesh(obj); }), HasSubstr(finite));
    EXPECT_THAT(ErrorOf([&] { ReadPoints(obj); }), HasSubstr("e.obj: line 3: v: z "));
    const std::string ply = Write("e.ply", BinaryPlySquare(z));
    EXPECT_THAT(ErrorOf([&] { ReadMesh(ply); }), HasSubstr("e.ply: element vertex 2: z "));
    EXPECT_THAT(ErrorOf([&] { ReadMesh(ply); }), HasSubstr(finite));
    // A mesh made in code (the Python Mesh) goes through Mesh::Check.
    Mesh mesh = SquareMesh(0.0);
    mesh.vertices[1].x = z;
    EXPECT_THAT(ErrorOf([&] { FocalSurface::FromMesh(mesh, "m"); }), HasSubstr("m: vertex 1: x "));
  }
  // A float PLY at 3e38 (float's edge) is refused too.
  std::string bytes;
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 3e38f}) Append(bytes, v);
  Append(bytes, uint8_t{3});
  for (int i = 0; i < 3; ++i) Append(bytes, int32_t{i});
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("f.ply", PlyWithCounts("binary_little_endian", 3, 1, bytes))); }),
              HasSubstr("f.ply: element vertex 2: z is 3.000000005e+38 m, beyond +-1000000000 m"));
  // A coordinate at the bound is read.
  EXPECT_EQ(ReadMesh(Write("edge.obj", "v 0 0 0\nv 1 0 0\nv 1 1 1e9\nf 1 2 3\n")).vertices[2].z, 1e9);
}

TEST_F(HeightfieldFiles, ExtremeHeightsAndPlacesAreRefusedNamingThePixel) {
  // DEM heights of 1e20 or +-3e38 (an undeclared nodata value) aborted the process in Embree.
  for (double value : {1e20, 3e38, -3e38, 5e9, double(std::numeric_limits<float>::infinity())}) {
    SCOPED_TRACE(Text(value));
    Heightfield field = TiltedField(4, 3, 1.0);
    field.heights[1 * 4 + 2] = static_cast<float>(value);  // pixel (2, 1)
    EXPECT_THAT(ErrorOf([&] { FocalSurface::FromHeightfield(field, "d.tif"); }),
                HasSubstr("d.tif: heights: pixel (2, 1) (column, row) "));
    // Written by GDAL itself (WriteHeightfield checks too): a raster read back.
    const std::string path = Path("extreme.tif");
    std::remove(path.c_str());
    {
      GDALAllRegister();
      GDALDatasetH dataset =
          GDALCreate(GDALGetDriverByName("GTiff"), path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
      double gt[6] = {0, 1, 0, 3, 0, -1};
      GDALSetGeoTransform(dataset, gt);
      GDALRasterIO(GDALGetRasterBand(dataset, 1), GF_Write, 0, 0, 4, 3, field.heights.data(), 4,
                   3, GDT_Float32, 0, 0);
      GDALClose(dataset);
    }
    EXPECT_THAT(ErrorOf([&] { FocalSurface::Read(path); }),
                HasSubstr("extreme.tif: heights: pixel (2, 1) (column, row) "));
  }
  // NaN is nodata, not an error; a raster placed at 1e20 is refused.
  Heightfield field = TiltedField(4, 3, 1.0);
  field.geotransform[3] = 1e20;
  EXPECT_THAT(ErrorOf([&] { FocalSurface::FromHeightfield(field, "far.tif"); }),
              HasSubstr("far.tif: geotransform: the raster's y range reaches a value that is 1e+20 m"));
}

TEST(SurfaceExtremes, PlanesDepthMapsPlacementsAndCamerasBeyondTheFloatRayCastAreRefused) {
  const LightField& light_field = Ground();
  for (double z : kExtremes) {
    SCOPED_TRACE(Text(z));
    // A plane given by numbers.
    EXPECT_THAT(ErrorOf([&] { FocalSurface::FromPlane(Plane::AtHeight(z)); }),
                HasSubstr("focal_surface: plane: point"));
    // A depth map whose pixel (3, 2) is that far (a depth map holds float32).
    const PinholeCamera camera = PinholeCamera::FromFov(6, 5, 50.0);
    Image depth(6, 5, 1, PixelType::kF32);
    for (int y = 0; y < 5; ++y) {
      for (int x = 0; x < 6; ++x) depth.At<float>(x, y)[0] = 10.0f;
    }
    const float as_float = static_cast<float>(std::abs(z));
    if (std::isfinite(as_float)) {
      depth.At<float>(3, 2)[0] = as_float;
      EXPECT_THAT(ErrorOf([&] { FocalSurface::FromDepthMap(depth, camera, NadirCamFromWorld(Vec3d(0, 0, 20))); }),
                  HasSubstr("depth: pixel (3, 2): depth "));
    }
    // A placement's origin or offset.
    SurfacePlacement placement;
    placement.origin.y = z;
    EXPECT_THAT(ErrorOf([&] { placement.Check(); }), HasSubstr("origin"));
    placement = SurfacePlacement();
    placement.offset = z;
    EXPECT_THAT(ErrorOf([&] { placement.Check(); }), HasSubstr("surface_offset"));
  }
  // Within kMaxSurfaceCoordinate but 2e7 m from the rest of the mesh: past kMaxRayCastRadius.
  Mesh spread = SquareMesh(0.0);
  spread.vertices[2] = Vec3d(4e7, 100, 0);
  EXPECT_THAT(ErrorOf([&] { FocalSurface::FromMesh(spread, "spread.obj"); }),
              HasSubstr("spread.obj: vertex 0 (-100, -100, 0) lies 10000075 m from the surface's "
                        "centroid (9999975, 0, 0); the float32 ray cast holds 10000000 m at most"));
  // A mesh 5e8 m away in world coordinates (a UTM DEM under a light field without an origin):
  // the camera is beyond kMaxRayOriginDistance of it; refused, not cast.
  Mesh far = SquareMesh(0.0);
  for (Vec3d& v : far.vertices) v.y += 5e8;
  const FocalSurface surface = FocalSurface::FromMesh(far, "far.obj");
  const PinholeCamera camera = PinholeCamera::FromFov(8, 8, 50.0);
  EXPECT_THAT(ErrorOf([&] { surface.DepthFor(camera, NadirCamFromWorld(Vec3d(0, 0, 20)), SurfacePlacement()); }),
              HasSubstr("cam_from_world: the virtual camera's centre lies 500000000 m from the centroid "
                        "of the focal surface far.obj"));
  // Offsets that move the ray origins 1e20 m (finite): refused naming offsets.
  const FocalSurface square = FocalSurface::FromMesh(SquareMesh(0.0), "sq.obj");
  std::vector<double> offsets(64, 0.5);
  offsets[9] = 1e20;
  EXPECT_THAT(ErrorOf([&] { square.DepthForOffsets(camera, NadirCamFromWorld(Vec3d(0, 0, 20)), SurfacePlacement(), offsets); }),
              HasSubstr("offsets: the virtual camera's centre moved by an offset of 1e+20 m lies"));
  // The map's vertical lines at 1e20 (or 5e8) miss, as they do geometrically; inside they hit.
  const std::vector<double> z = square.HeightsAt({{1e20, 0}, {0, -3e38}, {5e8, 5e8}, {1, 1}}, SurfacePlacement());
  EXPECT_TRUE(std::isnan(z[0]) && std::isnan(z[1]) && std::isnan(z[2]));
  EXPECT_EQ(z[3], 0.0);
}

TEST_F(MeshFiles, PlyHeaderCountsAreCheckedAgainstTheFileAndTheMemoryBudget) {
  // Before: 2e9 vertices in a 150-byte file reserved 48 GB: "error: std::bad_alloc", no file named.
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("huge.ply", PlyWithCounts("binary_little_endian", 2000000000, 1, std::string(40, '\0')))); }),
              HasSubstr("huge.ply: PLY header: element vertex 2000000000: the file cannot hold "
                        "that many (each takes at least 12 bytes (binary)"));
  EXPECT_THAT(ErrorOf([&] { ReadPoints(Write("huge.ply", PlyWithCounts("ascii", 2000000000, 0, "0 0 0\n"))); }),
              HasSubstr("huge.ply: PLY header: element vertex 2000000000: the file cannot hold"));
  // Faces: 4 vertices (48 bytes) and 1e9 faces of at least 1 byte in a file of 60.
  EXPECT_THAT(ErrorOf([&] { ReadMesh(Write("faces.ply", PlyWithCounts("binary_little_endian", 4, 1000000000, std::string(60, '\0')))); }),
              HasSubstr("faces.ply: PLY header: element face 1000000000: the file cannot hold"));
  // Counts the file holds but the memory budget does not: 60000 float vertices (720 kB on disk,
  // 1.44 MB as doubles) under a 1 MiB budget.
  std::string body(60000 * 12, '\0');
  const std::string path = Write("budget.ply", PlyWithCounts("binary_little_endian", 60000, 0, body));
  ::setenv("AOS_MEMORY_LIMIT_MB", "1", 1);
  const std::string message = ErrorOf([&] { ReadPoints(path); });
  ::unsetenv("AOS_MEMORY_LIMIT_MB");
  EXPECT_THAT(message, HasSubstr("budget.ply: PLY header: element vertex 60000, element face 0: "
                                 "needs 1 MiB of memory (their vertices and triangles)"));
  EXPECT_EQ(ReadPoints(path).size(), 60000u);
  // An OBJ's v and f lines are counted against the budget the same way: 50000 vertices.
  std::string obj;
  for (int i = 0; i < 50000; ++i) obj += "v 0 0 0\n";
  const std::string obj_path = Write("budget.obj", obj);
  ::setenv("AOS_MEMORY_LIMIT_MB", "1", 1);
  const std::string obj_message = ErrorOf([&] { ReadPoints(obj_path); });
  ::unsetenv("AOS_MEMORY_LIMIT_MB");
  EXPECT_THAT(obj_message, HasSubstr("budget.obj: mesh: 50000 vertices and 0 triangles: needs"));
  // An element without properties and an absurd count is nothing to read (it used to loop).
  EXPECT_EQ(ReadMesh(Write("empty_element.ply",
                           "ply\nformat ascii 1.0\nelement nothing 4000000000000000000\n"
                           "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")).triangles.size(), 1u);
}


TEST(FocalSurfaceHandle, AMovedFromSurfaceIsStillTheSurfaceItWas) {
  // The data is shared and immutable: moving copies the handle, so the source stays usable
  // (it used to be empty, and its first accessor dereferenced nothing).
  FocalSurface source = FocalSurface::FromPlane(Plane::AtHeight(12.5));
  FocalSurface moved = std::move(source);
  FocalSurface assigned = FocalSurface::FromPlane(Plane::AtHeight(0.0));
  assigned = std::move(moved);
  for (const FocalSurface* surface : {&source, &moved, &assigned}) {
    ASSERT_EQ(surface->kind(), FocalSurfaceKind::kPlane);
    EXPECT_DOUBLE_EQ(surface->plane().point.z, 12.5);
  }
}

}  // namespace
}  // namespace aos
