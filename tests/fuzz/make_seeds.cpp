// Writes the seed corpora of the fuzz harnesses: aos_fuzz_seeds <output folder> [<scenes folder>]
// makes <output folder>/<harness>/<seed> for every harness of tests/fuzz (the folder is
// replaced). Seeds are written with aos's own writers wherever there is one (WriteLightField,
// WriteCameraFile, SceneToJson, WriteFocalStack, WriteImage), so they follow the formats as the
// code stands; the JKU poses and COLMAP models are written here from their documented layouts.
// Frames and slice images that seeds name are the harnesses' fixtures (fuzz_util.h).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "aos/geometry/lens.h"
#include "aos/geometry/mesh.h"
#include "aos/geometry/rigid.h"
#include "aos/lightfield/camera_file.h"
#include "aos/lightfield/formats.h"
#include "aos/render/focal_stack.h"
#include "aos/sim/scene.h"
#include "../cpp/gps_frame.h"
#include "fuzz_util.h"

namespace {

namespace fs = std::filesystem;
using aos_fuzz::kFrameHeight;
using aos_fuzz::kFrameWidth;

std::string ReadAll(const fs::path& path) {
  std::ifstream file(path, std::ios::binary);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

// `text` with every occurrence of `from` replaced by `to`.
std::string ReplaceAll(std::string text, const std::string& from, const std::string& to) {
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
  return text;
}

aos::Rigid3d NadirPose(double x, double y, double altitude) {
  return aos::LookAt(aos::Vec3d(x, y, altitude), aos::Vec3d(x, y, 0.0), aos::Vec3d(0, 1, 0));
}

aos::LensCamera Lens(aos::LensModel model, std::array<double, 5> distortion, double xi = 0.0) {
  aos::LensCamera lens;
  lens.model = model;
  lens.width = kFrameWidth;
  lens.height = kFrameHeight;
  lens.fx = lens.fy = 7.0;
  lens.cx = kFrameWidth / 2.0;
  lens.cy = kFrameHeight / 2.0;
  lens.distortion = distortion;
  lens.xi = xi;
  lens.Finalize("seed lens");
  return lens;
}

// --- light fields --------------------------------------------------------------------------

void LightFieldSeeds(const fs::path& work, const fs::path& out) {
  const aos::PinholeCamera pinhole =
      aos::PinholeCamera::FromFov(kFrameWidth, kFrameHeight, 50.0);
  const aos::LensCamera lenses[] = {
      aos::LensCamera::FromPinhole(pinhole), aos::LensCamera::FromPinhole(pinhole),
      Lens(aos::LensModel::kRadTan, {-0.05, 0.01, 0.001, -0.001, 0.0}),
      Lens(aos::LensModel::kOmnidir, {-0.1, 0.02, 0.0, 0.0, 0.0}, 0.8)};
  for (int variant = 0; variant < 2; ++variant) {
    aos::LightField light_field;
    light_field.origin = aos::Vec3d(543210.5, 5432109.25, 312.0);
    for (int i = 0; i < 4; ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "views/%04d.png", i);
      aos::View view;
      view.name = name;
      view.image_path = (work / name).string();
      view.camera = variant == 0 ? aos::LensCamera::FromPinhole(pinhole) : lenses[i];
      view.cam_from_world = NadirPose(i % 2, i / 2, 20.0);
      light_field.views.push_back(view);
    }
    if (variant == 0) {
      aos::PoseSource source;
      source.method = "colmap";
      source.mean_reprojection_error_px = 0.4;
      source.median_depth = 20.0;
      source.pose_error = 0.01;
      source.georeferenced = true;
      source.georeference_rms_m = 0.2;
      source.world_frame = "UTM 33N (WGS84)";
      source.unregistered = {"views/rgb.png"};
      light_field.pose_source = source;
    }
    const fs::path path = work / "lf.json";
    aos::WriteLightField(path.string(), light_field);
    fs::copy_file(path, out / (variant == 0 ? "aos_pinhole.json" : "aos_lenses.json"));
  }
  // A camera given by its field of view, and frames of every fixture type.
  aos_fuzz::WriteText(out / "aos_fov.json", R"({
  "format": "aos-lightfield", "version": 1, "origin": [0, 0, 0],
  "cameras": {"c": {"model": "pinhole", "width": 8, "height": 6, "fov_deg": 60},
              "big": {"model": "pinhole", "width": 16, "height": 12, "fx": 14, "fy": 14, "cx": 8, "cy": 6}},
  "views": [
    {"image": "views/16bit.tif", "camera": "c",
     "cam_from_world": {"rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "translation": [0, 0, 20]}},
    {"image": "views/float.exr", "camera": "c",
     "cam_from_world": {"rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "translation": [1, 0, 20]}},
    {"image": "views/photo.jpg", "camera": "c",
     "cam_from_world": {"rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "translation": [0, 1, 20]}},
    {"image": "views/big.png", "camera": "big",
     "cam_from_world": {"rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "translation": [1, 1, 20]}}
  ]
}
)");
  aos_fuzz::WriteText(out / "aos_rgb.json", R"({"format": "aos-lightfield", "version": 1,
 "cameras": {"c": {"model": "radtan", "width": 8, "height": 6, "fx": 7, "fy": 7, "cx": 4, "cy": 3,
                   "distortion": [-0.05, 0.01, 0, 0, 0]}},
 "views": [{"image": "views/rgb.png", "camera": "c",
            "cam_from_world": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "translation": [0, 0, 5]}}]}
)");
  // JKU poses: numbers and numeric strings; frames in ../images, one found under another
  // extension (0004.tif -> 0004.tiff).
  aos_fuzz::WriteText(out / "jku_poses.json", R"({"images": [
  {"imagefile": "0000.png", "M3x4": [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 20]]},
  {"imagefile": "0001.png", "M3x4": [["1.0", "0", "0", "-1.5"], ["0", "-1", "0", "0"], ["0", "0", "-1", "20"]]},
  {"imagefile": "0002.png", "M3x4": [[0.9998476951563913, -0.01745240643728351, 0, 0.5],
                                     [-0.01745240643728351, -0.9998476951563913, 0, 1],
                                     [0, 0, -1, 20.5]]},
  {"imagefile": "0004.tif", "M3x4": [[1, 0, 0, 2], [0, -1, 0, 2], [0, 0, -1, 19]]}
]}
)");
}

// --- camera files --------------------------------------------------------------------------

void CameraFileSeeds(const fs::path& work, const fs::path& out) {
  struct Seed {
    const char* name;
    aos::LensCamera lens;
    const char* calibration;
  };
  aos::LensCamera pinhole =
      aos::LensCamera::FromPinhole(aos::PinholeCamera::FromFov(640, 480, 70.0));
  aos::LensCamera radtan = Lens(aos::LensModel::kRadTan, {-0.2, 0.05, 0.001, -0.002, 0.01});
  radtan.width = 640, radtan.height = 480, radtan.fx = radtan.fy = 500, radtan.cx = 320,
  radtan.cy = 240;
  radtan.Finalize("seed");
  aos::LensCamera fisheye = Lens(aos::LensModel::kFisheye, {0.01, -0.002, 0.0003, 0.0, 0.0});
  aos::LensCamera omnidir = Lens(aos::LensModel::kOmnidir, {-0.1, 0.02, 0.001, 0.0, 0.0}, 1.2);
  omnidir.skew = 0.001;
  omnidir.Finalize("seed");
  const Seed seeds[] = {
      {"pinhole.json", pinhole, ""},
      {"radtan.json", radtan, R"({"rms_px": 0.31, "frames": 24, "board": [9, 6]})"},
      {"fisheye.json", fisheye, R"({"rms_px": 0.5})"},
      {"omnidir.json", omnidir, ""},
  };
  for (const Seed& seed : seeds) {
    const fs::path path = work / seed.name;
    aos::WriteCameraFile(path.string(), seed.lens, seed.calibration);
    fs::copy_file(path, out / seed.name);
  }
}

// --- scenes --------------------------------------------------------------------------------

void SceneSeeds(const fs::path& work, const fs::path& scenes, const fs::path& out) {
  aos_fuzz::WriteText(out / "default.json", aos::SceneToJson(aos::DefaultScene()));
  std::error_code error;
  for (fs::directory_iterator it(scenes, error), end; !error && it != end; it.increment(error)) {
    if (it->path().extension() == ".json") fs::copy_file(it->path(), out / it->path().filename());
  }
  // Everything else a scene can name: an image texture, a stepped height field, a lens camera,
  // explicit positions, every effect. Written through SceneToJson; the fixture's folder is cut
  // from the texture's path so the seed names "texture.png" beside the scene.
  aos::Scene scene = aos::DefaultScene();
  scene.ground.texture.kind = aos::TextureSpec::Kind::kImage;
  scene.ground.texture.image_path = (work / "texture.png").string();
  scene.ground.texture.size = {4.0, 4.0};
  scene.ground.steps.push_back(aos::StepSpec{{1.0, 0.0}, {1.0, 0.5}, 0.4});
  scene.ground.cell_size = 0.25;
  scene.ground.extent = {-10, -10, 10, 10};
  aos::TargetSpec target;
  target.texture.kind = aos::TextureSpec::Kind::kNoise;
  target.texture.seed = 3;
  scene.targets.push_back(target);
  scene.has_voxels = false;
  scene.has_trees = true;
  scene.trees.area = {-10, -10, 10, 10};
  scene.trees.leaves_per_tree = 20;
  scene.camera.width = 32;
  scene.camera.height = 24;
  scene.camera.lens = "fisheye";
  scene.camera.fov_deg = 120.0;
  scene.camera.distortion = {0.01, 0.0, 0.0, 0.0, 0.0};
  scene.camera.channels = 3;
  scene.camera.bit_depth = 16;
  scene.camera.samples_per_pixel = 2;
  scene.sampling.positions = {{0, 0, 20}, {1, 0, 20}, {0, 1, 21}};
  scene.effects.pose_noise = true;
  scene.effects.pose_noise_spec.position_sigma_cm = 2.0;
  scene.effects.sensor_noise = true;
  scene.effects.sensor_noise_spec.sigma = 0.01;
  scene.effects.sun = true;  // thermal needs one channel: thermal_person.json has it
  scene.truth.fov_deg = 40.0;
  scene.truth.width = 16;
  scene.truth.height = 16;
  std::string text;
  try {
    text = aos::SceneToJson(scene);
    aos::ParseScene(text, "seed", work.string());
  } catch (const std::invalid_argument& error) {
    std::fprintf(stderr, "aos_fuzz_seeds: the full scene seed does not parse (%s); skipped\n",
                 error.what());
    return;
  }
  aos_fuzz::WriteText(out / "everything.json", ReplaceAll(text, work.string() + "/", ""));
}

// --- focal stacks --------------------------------------------------------------------------

void FocalStackSeeds(const fs::path& work, const fs::path& out) {
  for (int variant = 0; variant < 2; ++variant) {
    aos::FocalStack stack;
    stack.camera = aos::PinholeCamera::FromFov(kFrameWidth, kFrameHeight, 60.0);
    stack.cam_from_world = NadirPose(0.0, 0.0, 30.0);
    stack.render.width = kFrameWidth;
    stack.render.height = kFrameHeight;
    stack.render.fov_deg = 60.0;
    stack.render.variance = variant == 0;
    stack.render.view_indices = variant == 0 ? std::vector<int>{} : std::vector<int>{0, 2, 3};
    if (variant == 1) stack.render.aperture_radius = std::numeric_limits<double>::infinity();
    const int slices = variant == 0 ? 2 : 1;
    for (int i = 0; i < slices; ++i) {
      stack.focus.planes.push_back(variant == 0 ? aos::Plane::AtHeight(i * 5.0)
                                                : aos::Plane{aos::Vec3d(0, 0, 2), aos::Vec3d(0.1, 0, 1)});
      stack.images.push_back(aos_fuzz::Pattern(kFrameWidth, kFrameHeight, 1, aos::PixelType::kF32, i));
      stack.counts.push_back(aos_fuzz::Pattern(kFrameWidth, kFrameHeight, 1, aos::PixelType::kU32, i));
      if (variant == 0) {
        stack.variances.push_back(
            aos_fuzz::Pattern(kFrameWidth, kFrameHeight, 1, aos::PixelType::kF32, i + 2));
      }
    }
    const fs::path folder = work / ("stack" + std::to_string(variant));
    aos::WriteFocalStack(folder.string(), stack);
    fs::copy_file(folder / "stack.json", out / ("stack" + std::to_string(variant) + ".json"));
  }
}

// --- COLMAP models -------------------------------------------------------------------------

const char* kCamerasText =
    "# Camera list with one line of data per camera:\n"
    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    "# Number of cameras: 3\n"
    "1 PINHOLE 8 6 7.5 7.5 4 3\n"
    "2 OPENCV 640 480 500 501 320 240 -0.1 0.01 0.001 -0.001\n"
    "3 SIMPLE_RADIAL_FISHEYE 640 480 300 320 240 0.02\n";
const char* kImagesText =
    "# Image list with two lines of data per image:\n"
    "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
    "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
    "# Number of images: 3, mean observations per image: 2\n"
    "1 0.7071067811865476 0.7071067811865476 0 0 0.1 -0.2 3.5 1 a.png\n"
    "1.5 2.5 1 3.25 4.75 -1 6 1 2\n"
    "2 1 0 0 0 0 0 0 2 sub/b with space.jpg\n"
    "\n"
    "3 0 0 1 0 1e-3 2E+1 -3 3 c.tif\n"
    "100.5 200.25 3\n";
const char* kPointsText =
    "# 3D point list with one line of data per point:\n"
    "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
    "# Number of points: 3, mean track length: 1.3\n"
    "1 0.5 -0.25 10 255 128 0 0.75 1 0\n"
    "2 1 2 3 0 0 0 -1 1 1 3 0\n"
    "3 -1 -2 -3 10 20 30 1.5\n";

struct Binary {
  std::string bytes;
  template <class T>
  void Put(T value) {
    char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));  // x86-64 is little-endian, as the format
    bytes.append(raw, sizeof(T));
  }
  void Name(const std::string& name) { bytes.append(name.c_str(), name.size() + 1); }
};

void ColmapSeeds(const fs::path& out_text, const fs::path& out_binary) {
  const std::string separator = aos_fuzz::kFileSeparator;
  aos_fuzz::WriteText(out_text / "model.txt",
                      std::string(kCamerasText) + separator + kImagesText + separator + kPointsText);
  aos_fuzz::WriteText(out_text / "minimal.txt",
                      std::string("1 SIMPLE_PINHOLE 8 6 7 4 3\n") + separator +
                          "1 1 0 0 0 0 0 0 1 a.png\n" + separator);

  Binary cameras, images, points;
  cameras.Put<uint64_t>(3);
  // id, model id (1 PINHOLE, 4 OPENCV, 5 OPENCV_FISHEYE), width, height, params.
  cameras.Put<uint32_t>(1), cameras.Put<int32_t>(1), cameras.Put<uint64_t>(8), cameras.Put<uint64_t>(6);
  for (double p : {7.5, 7.5, 4.0, 3.0}) cameras.Put(p);
  cameras.Put<uint32_t>(2), cameras.Put<int32_t>(4), cameras.Put<uint64_t>(640), cameras.Put<uint64_t>(480);
  for (double p : {500.0, 501.0, 320.0, 240.0, -0.1, 0.01, 0.001, -0.001}) cameras.Put(p);
  cameras.Put<uint32_t>(7), cameras.Put<int32_t>(5), cameras.Put<uint64_t>(640), cameras.Put<uint64_t>(480);
  for (double p : {300.0, 300.0, 320.0, 240.0, 0.01, -0.002, 0.0003, 0.0}) cameras.Put(p);

  images.Put<uint64_t>(2);
  images.Put<uint32_t>(1);
  for (double q : {0.7071067811865476, 0.7071067811865476, 0.0, 0.0}) images.Put(q);
  for (double t : {0.1, -0.2, 3.5}) images.Put(t);
  images.Put<uint32_t>(1);
  images.Name("a.png");
  images.Put<uint64_t>(2);
  images.Put(1.5), images.Put(2.5), images.Put<uint64_t>(1);
  images.Put(3.0), images.Put(4.0), images.Put<uint64_t>(UINT64_MAX);
  images.Put<uint32_t>(5);
  for (double q : {1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}) images.Put(q);
  images.Put<uint32_t>(7);
  images.Name("sub/b.jpg");
  images.Put<uint64_t>(0);

  points.Put<uint64_t>(2);
  points.Put<uint64_t>(1);
  for (double x : {0.5, -0.25, 10.0}) points.Put(x);
  points.Put<uint8_t>(255), points.Put<uint8_t>(128), points.Put<uint8_t>(0);
  points.Put(0.75);
  points.Put<uint64_t>(1), points.Put<uint32_t>(1), points.Put<uint32_t>(0);
  points.Put<uint64_t>(9);
  for (double x : {1.0, 2.0, 3.0}) points.Put(x);
  points.Put<uint8_t>(1), points.Put<uint8_t>(2), points.Put<uint8_t>(3);
  points.Put(-1.0);
  points.Put<uint64_t>(0);
  aos_fuzz::WriteText(out_binary / "model.bin",
                      cameras.bytes + separator + images.bytes + separator + points.bytes);
  Binary empty;
  empty.Put<uint64_t>(0);
  aos_fuzz::WriteText(out_binary / "empty_points.bin",
                      cameras.bytes + separator + images.bytes + separator + empty.bytes);
}

// --- CSV: telemetry logs and positions files ---------------------------------------------

// Telemetry logs for the four fixture frames 0000.png .. 0003.png (csv_fuzzer.cpp): by frame
// name (with aliases, comments, CRLF), and by time (interpolated at 1 s per frame).
void TelemetryCsvSeeds(const fs::path& out) {
  aos_fuzz::WriteText(out / "frames.csv",
                      "frame,lat,lon,alt,yaw,pitch,roll\n"
                      "0000.png,48.0000000000,15.0,120.0,0,-90,0\n"
                      "0001.png,48.0001000000,15.0,120.5,0,-90,0\n"
                      "0002.png,48.0002000000,15.0,121.0,10,-90,0\n"
                      "0003.png,48.0003000000,15.0,119.5,350.5,-89.5,0.5\n");
  aos_fuzz::WriteText(out / "aliases.csv",
                      "# DJI-style log\r\nName, Latitude, Longitude, Altitude, Heading, Pitch, "
                      "Roll\r\n\r\n0000.png, -33.5, -70.25, 50, 180, -90, 0\r\n"
                      "0001.png, -33.5001, -70.25, 50, 180, -90, 0\r\n"
                      "0002.png, -33.5002, -70.25, 50, 180, -90, 0\r\n"
                      "0003.png, -33.5003, -70.25, 50, 180, -90, 0\r\n");
  aos_fuzz::WriteText(out / "time.csv",
                      "time,lat,lon,alt,yaw,pitch,roll\n"
                      "-0.5,48.0,15.0,120.0,0,-90,0\n"
                      "1.25,48.0001,15.0,120.0,359,-90,0\n"
                      "2.5,48.0002,15.0,120.0,1,-90,0\n"
                      "4.0,48.0003,15.0,120.0,0,-90,0\n");
}

// Positions files (csv_fuzzer.cpp): name,x,y,z without a header (UTM metres), a header naming
// x, y, z in another order, and latitude/longitude columns (degrees). The harness states
// EPSG:32633 when the input's first byte is odd ('a', '#'), no CRS when it is even ('n').
void PositionsCsvSeeds(const fs::path& out) {
  aos_fuzz::WriteText(out / "plain.csv",
                      "a.png,543210.5,5432109.25,312.0\nb.png,543211.5,5432109.25,312.5\n"
                      "c.png,543212.5,5432110.25,313.0\n");
  aos_fuzz::WriteText(out / "header.csv",
                      "# positions\nz, name, y, x\n312, views/a.png, 5432109.25, 543210.5\n"
                      "312.5, views/b.png, 5432109.25, 543211.5\n");
  aos_fuzz::WriteText(out / "latlon.csv",
                      "name,latitude,longitude,altitude\r\nA.JPG,48.0,15.0,400\r\n"
                      "B.JPG,48.0001,15.0001,401\r\nC.JPG,48.0002,15.0,402\r\n");
}

// --- meshes -------------------------------------------------------------------------------

// OBJ (mesh_obj) and PLY (mesh_ply) seeds: a triangle and a quad in UTM-like world coordinates,
// corners in every OBJ form (v, v/vt, v/vt/vn, v//vn, negative), ascii PLY with extra
// properties and elements, binary PLY written by aos's own WritePly.
void MeshSeeds(const fs::path& work, const fs::path& out_obj, const fs::path& out_ply) {
  aos_fuzz::WriteText(out_obj / "quad.obj",
                      "# terrain\nmtllib t.mtl\no ground\nv 543200 5432100 300\n"
                      "v 543260 5432100 301.5\nv 543260 5432160 302\nv 543200 5432160 300.5 1\n"
                      "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\ns off\nf 1/1/1 2/2/1 3/3/1 4//1\n");
  aos_fuzz::WriteText(out_obj / "negative.obj",
                      "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 1 1 0.5\nf 2 4 3\nf 1 1 2\n");
  aos_fuzz::WriteText(out_ply / "ascii.ply",
                      "ply\nformat ascii 1.0\ncomment aos seed\nelement vertex 4\n"
                      "property float x\nproperty float y\nproperty double z\n"
                      "property uchar red\nelement face 2\n"
                      "property list uchar int vertex_indices\nelement edge 1\n"
                      "property int vertex1\nproperty int vertex2\nend_header\n"
                      "0 0 10 255\n4 0 10.5 0\n4 4 11 7\n0 4 10 9\n3 0 1 2\n4 0 2 3 1\n0 1\n");
  const std::vector<aos::Vec3d> vertices = {
      {543200.0, 5432100.0, 300.0}, {543260.0, 5432100.0, 301.5},
      {543260.0, 5432160.0, 302.0}, {543200.0, 5432160.0, 300.5}};
  const fs::path binary = work / "seed_binary.ply";
  fs::remove(binary);
  aos::WritePly(binary.string(), vertices, {{0, 1, 2}, {0, 2, 3}});
  fs::copy_file(binary, out_ply / "binary.ply");
  const fs::path points = work / "seed_points.ply";
  fs::remove(points);
  aos::WritePly(points.string(), vertices);
  fs::copy_file(points, out_ply / "points.ply");
}

// --- images --------------------------------------------------------------------------------

// A small frame with the GPS tags a drone writes (ReadGpsTag).
void WriteGpsTagged(const fs::path& path, double lat, double lon, double altitude) {
  if (!aos::testing_util::WriteGpsTaggedFrame(path.string(), 8, 6, lat, lon, altitude)) {
    throw std::runtime_error(path.string() + ": cannot write the GPS-tagged seed");
  }
}

void ImageSeeds(const fs::path& work, const fs::path& out, const std::string& extension) {
  using aos::PixelType;
  struct Kind {
    const char* name;
    int width, height, channels;
    PixelType type;
    aos::SampleType sample_type;
  };
  // Types each format stores (WriteImage converts to the sample type asked for).
  std::vector<Kind> kinds;
  if (extension == ".png") {
    kinds = {{"grey8", 8, 6, 1, PixelType::kU8, aos::SampleType::kU8},
             {"rgb8", 5, 3, 3, PixelType::kU8, aos::SampleType::kU8},
             {"rgb16", 4, 4, 3, PixelType::kU16, aos::SampleType::kU16},
             {"grey16", 1, 1, 1, PixelType::kU16, aos::SampleType::kU16},
             {"rgba8", 4, 4, 4, PixelType::kU8, aos::SampleType::kU8}};
  } else if (extension == ".tif") {
    kinds = {{"float", 8, 6, 1, PixelType::kF32, aos::SampleType::kF32},
             {"u16", 8, 6, 1, PixelType::kU16, aos::SampleType::kU16},
             {"u32", 8, 6, 1, PixelType::kU32, aos::SampleType::kU32},
             {"rgb8", 5, 3, 3, PixelType::kU8, aos::SampleType::kU8}};
  } else if (extension == ".exr") {
    kinds = {{"grey", 8, 6, 1, PixelType::kF32, aos::SampleType::kF32},
             {"rgba", 5, 3, 4, PixelType::kF32, aos::SampleType::kF32}};
  } else {
    kinds = {{"grey", 8, 6, 1, PixelType::kU8, aos::SampleType::kU8},
             {"rgb", 16, 8, 3, PixelType::kU8, aos::SampleType::kU8}};
  }
  int seed = 0;
  for (const Kind& kind : kinds) {
    const fs::path path = work / (std::string("seed_") + kind.name + extension);
    aos::WriteImageOptions options;
    options.sample_type = kind.sample_type;
    options.range_max = 1.0;
    options.description = "aos fuzz seed";
    try {
      aos::WriteImage(path.string(),
                      aos_fuzz::Pattern(kind.width, kind.height, kind.channels, kind.type, seed++),
                      options);
    } catch (const std::invalid_argument& error) {
      // WriteImage checks that the file reads back intact and may refuse a kind; the rest
      // still make seeds.
      std::fprintf(stderr, "aos_fuzz_seeds: %s seed skipped: %s\n", kind.name, error.what());
      continue;
    }
    fs::copy_file(path, out / (std::string(kind.name) + extension));
  }
  if (extension == ".jpg" || extension == ".tif") {
    const fs::path path = work / (std::string("seed_gps") + extension);
    WriteGpsTagged(path, -33.5, -70.25, -12.0);
    fs::copy_file(path, out / (std::string("gps") + extension));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: %s <output folder> [<scenes folder>]\n", argv[0]);
    return 2;
  }
  try {
    const fs::path out = argv[1];
    const fs::path scenes = argc > 2 ? fs::path(argv[2]) : fs::path();
    const fs::path work = aos_fuzz::WorkDir("seeds");
    fs::remove_all(out);
    const auto folder = [&](const char* harness) {
      fs::create_directories(out / harness);
      return out / harness;
    };
    LightFieldSeeds(work, folder("lightfield"));
    CameraFileSeeds(work, folder("camera_file"));
    SceneSeeds(work, scenes, folder("scene"));
    FocalStackSeeds(work, folder("focal_stack"));
    ColmapSeeds(folder("colmap_text"), folder("colmap_binary"));
    TelemetryCsvSeeds(folder("telemetry_csv"));
    PositionsCsvSeeds(folder("positions_csv"));
    MeshSeeds(work, folder("mesh_obj"), folder("mesh_ply"));
    for (const char* extension : {".png", ".tif", ".exr", ".jpg"}) {
      ImageSeeds(work, folder((std::string("image_") + (extension + 1)).c_str()), extension);
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "aos_fuzz_seeds: %s\n", error.what());
    return 1;
  }
  return 0;
}
