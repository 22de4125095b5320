// Tests of the COLMAP import (colmap_model.h) and of geo-referencing by a similarity transform
// (similarity.h). The COLMAP models are written by the test itself, in both of COLMAP's formats
// (layouts from COLMAP's reconstruction_io_{text,binary}.cc), so COLMAP need not be installed.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "error_of.h"
#include "gps_frame.h"
#include "temp_folder.h"

#include "aos/geometry/similarity.h"
#include "aos/image/image_io.h"
#include "aos/sfm/colmap_model.h"

namespace aos {
namespace {

namespace fs = std::filesystem;
using test_util::ErrorOf;
using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// A COLMAP model as the test writes it.

struct TestCamera {
  uint32_t id;
  int model_id;  // COLMAP's CameraModelId
  std::string model;
  uint64_t width, height;
  std::vector<double> params;
};

struct TestImage {
  uint32_t id;
  std::array<double, 4> qvec;  // w, x, y, z (not necessarily normalised)
  std::array<double, 3> tvec;
  uint32_t camera_id;
  std::string name;
  std::vector<std::pair<Vec2d, int64_t>> points2d;  // -1 = no 3-D point
};

struct TestPoint {
  uint64_t id;
  Vec3d xyz;
  std::array<uint8_t, 3> rgb;
  double error;
  std::vector<std::pair<uint32_t, uint32_t>> track;
};

struct TestModel {
  std::vector<TestCamera> cameras;
  std::vector<TestImage> images;
  std::vector<TestPoint> points;
};

// The quaternion of a rotation by `angle` about `axis`, scaled by `norm` (COLMAP normalises).
std::array<double, 4> Quaternion(Vec3d axis, double angle, double norm = 1.0) {
  axis = glm::normalize(axis);
  const double s = std::sin(angle / 2);
  return {norm * std::cos(angle / 2), norm * s * axis.x, norm * s * axis.y, norm * s * axis.z};
}

// Rodrigues' formula, independent of the reader's quaternion formula.
Mat3d AxisAngle(Vec3d axis, double angle) {
  axis = glm::normalize(axis);
  const Mat3d k = MatFromRows(Vec3d(0, -axis.z, axis.y), Vec3d(axis.z, 0, -axis.x),
                              Vec3d(-axis.y, axis.x, 0));
  return Mat3d(1.0) + std::sin(angle) * k + (1 - std::cos(angle)) * (k * k);
}

TestModel MakeModel() {
  TestModel model;
  model.cameras = {
      {1, 0, "SIMPLE_PINHOLE", 64, 48, {70.5, 32.25, 23.75}},
      {7, 4, "OPENCV", 64, 48, {71.25, 70.125, 31.5, 24.5, -0.05, 0.01, 0.001, -0.002}},
      {3, 5, "OPENCV_FISHEYE", 80, 60, {40.1, 40.3, 40.2, 29.9, 0.02, -0.01, 0.003, -0.0004}},
      {12, 7, "FOV", 64, 48, {60, 61, 32, 24, 0.9}},
  };
  model.images = {
      {5, Quaternion(Vec3d(0.2, -1, 0.3), 0.7, 2.5), {0.5, -1.25, 3.0}, 7, "frames/b.png",
       {{Vec2d(1.5, 2.5), 100}, {Vec2d(10.25, 3.0), -1}, {Vec2d(30.5, 40.75), 101}}},
      {2, Quaternion(Vec3d(1, 1, 0), -2.9), {1e-3, 2e-3, -7.0}, 1, "a name with spaces.png", {}},
      {9, Quaternion(Vec3d(0, 0, 1), 0.0), {0, 0, 0}, 3, "c.png",
       {{Vec2d(0.125, 59.875), 100}, {Vec2d(5, 6), 102}}},
  };
  model.points = {
      {100, Vec3d(1.5, -2.25, 10.125), {255, 0, 17}, 0.5, {{5, 0}, {9, 0}}},
      {101, Vec3d(-3.0, 0.0625, 8.0), {1, 2, 3}, 1.5, {{5, 2}}},
      {102, Vec3d(0.1, 0.2, 0.3), {9, 9, 9}, -1.0, {{9, 1}}},
  };
  return model;
}

std::string Text(double value) {
  std::ostringstream stream;
  stream.precision(17);
  stream << value;
  return stream.str();
}

void WriteFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

// The text files as COLMAP writes them (comment header, 17 significant digits).
void WriteText(const fs::path& folder, const TestModel& model) {
  std::string cameras = "# Camera list with one line of data per camera:\n"
                        "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: " +
                        std::to_string(model.cameras.size()) + "\n";
  for (const TestCamera& c : model.cameras) {
    cameras += std::to_string(c.id) + " " + c.model + " " + std::to_string(c.width) + " " +
               std::to_string(c.height);
    for (double p : c.params) cameras += " " + Text(p);
    cameras += "\n";
  }
  std::string images = "# Image list with two lines of data per image:\n"
                       "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                       "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (const TestImage& i : model.images) {
    images += std::to_string(i.id);
    for (double q : i.qvec) images += " " + Text(q);
    for (double t : i.tvec) images += " " + Text(t);
    images += " " + std::to_string(i.camera_id) + " " + i.name + "\n";
    std::string line;
    for (const auto& [xy, id] : i.points2d) {
      line += (line.empty() ? "" : " ") + Text(xy.x) + " " + Text(xy.y) + " " + std::to_string(id);
    }
    images += line + "\n";
  }
  std::string points = "# 3D point list with one line of data per point:\n"
                       "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, "
                       "POINT2D_IDX)\n";
  for (const TestPoint& p : model.points) {
    points += std::to_string(p.id) + " " + Text(p.xyz.x) + " " + Text(p.xyz.y) + " " +
              Text(p.xyz.z);
    for (uint8_t c : p.rgb) points += " " + std::to_string(c);
    points += " " + Text(p.error);
    for (const auto& [image, index] : p.track) {
      points += " " + std::to_string(image) + " " + std::to_string(index);
    }
    points += "\n";
  }
  WriteFile(folder / "cameras.txt", cameras);
  WriteFile(folder / "images.txt", images);
  WriteFile(folder / "points3D.txt", points);
}

// Little-endian appends.
template <typename T>
void Put(std::string* bytes, T value) {
  uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof(T));
  for (size_t i = 0; i < sizeof(T); ++i) {
    bytes->push_back(static_cast<char>((bits >> (8 * i)) & 0xff));
  }
}

std::string CamerasBinary(const TestModel& model) {
  std::string bytes;
  Put<uint64_t>(&bytes, model.cameras.size());
  for (const TestCamera& c : model.cameras) {
    Put<uint32_t>(&bytes, c.id);
    Put<int32_t>(&bytes, c.model_id);
    Put<uint64_t>(&bytes, c.width);
    Put<uint64_t>(&bytes, c.height);
    for (double p : c.params) Put<double>(&bytes, p);
  }
  return bytes;
}

std::string ImagesBinary(const TestModel& model) {
  std::string bytes;
  Put<uint64_t>(&bytes, model.images.size());
  for (const TestImage& i : model.images) {
    Put<uint32_t>(&bytes, i.id);
    for (double q : i.qvec) Put<double>(&bytes, q);
    for (double t : i.tvec) Put<double>(&bytes, t);
    Put<uint32_t>(&bytes, i.camera_id);
    bytes += i.name;
    bytes.push_back('\0');
    Put<uint64_t>(&bytes, i.points2d.size());
    for (const auto& [xy, id] : i.points2d) {
      Put<double>(&bytes, xy.x);
      Put<double>(&bytes, xy.y);
      Put<int64_t>(&bytes, id);  // -1 = all ones = COLMAP's kInvalidPoint3DId
    }
  }
  return bytes;
}

std::string PointsBinary(const TestModel& model) {
  std::string bytes;
  Put<uint64_t>(&bytes, model.points.size());
  for (const TestPoint& p : model.points) {
    Put<uint64_t>(&bytes, p.id);
    for (int k = 0; k < 3; ++k) Put<double>(&bytes, p.xyz[k]);
    for (uint8_t c : p.rgb) Put<uint8_t>(&bytes, c);
    Put<double>(&bytes, p.error);
    Put<uint64_t>(&bytes, p.track.size());
    for (const auto& [image, index] : p.track) {
      Put<uint32_t>(&bytes, image);
      Put<uint32_t>(&bytes, index);
    }
  }
  return bytes;
}

void WriteBinary(const fs::path& folder, const TestModel& model) {
  WriteFile(folder / "cameras.bin", CamerasBinary(model));
  WriteFile(folder / "images.bin", ImagesBinary(model));
  WriteFile(folder / "points3D.bin", PointsBinary(model));
}

void ExpectMatches(const ColmapModel& read, const TestModel& model) {
  ASSERT_EQ(read.cameras.size(), model.cameras.size());
  for (size_t i = 0; i < model.cameras.size(); ++i) {
    const ColmapCamera& c = read.cameras[i];
    EXPECT_EQ(c.camera_id, model.cameras[i].id);
    EXPECT_EQ(c.model, model.cameras[i].model);
    EXPECT_EQ(static_cast<uint64_t>(c.width), model.cameras[i].width);
    EXPECT_EQ(static_cast<uint64_t>(c.height), model.cameras[i].height);
    EXPECT_EQ(c.params, model.cameras[i].params);  // bit-exact (17 digits round-trip)
  }
  ASSERT_EQ(read.images.size(), model.images.size());
  size_t observations = 0;
  for (size_t i = 0; i < model.images.size(); ++i) {
    const ColmapImage& image = read.images[i];
    const TestImage& expected = model.images[i];
    EXPECT_EQ(image.image_id, expected.id);
    EXPECT_EQ(image.name, expected.name);
    EXPECT_EQ(image.camera_id, expected.camera_id);
    EXPECT_EQ(image.num_points2d, expected.points2d.size());
    size_t with_point = 0;
    for (const auto& point : expected.points2d) with_point += point.second != -1;
    EXPECT_EQ(image.num_observations, with_point);
    observations += with_point;
    // The rotation of the normalised quaternion: Rodrigues from the same axis and angle.
    const auto& q = expected.qvec;
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double angle = 2.0 * std::atan2(std::sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), q[0]);
    const Mat3d rotation = angle == 0.0 ? Mat3d(1.0)
                                        : AxisAngle(Vec3d(q[1], q[2], q[3]) / norm, angle);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(image.cam_from_world.rotation[c][r], rotation[c][r], 4e-15) << i;
      }
      EXPECT_EQ(image.cam_from_world.translation[r], expected.tvec[r]);
    }
    EXPECT_FALSE(DescribeInvalidRigid(image.cam_from_world, 1e-14).has_value());
  }
  EXPECT_EQ(read.num_observations, observations);
  ASSERT_EQ(read.points.size(), model.points.size());
  for (size_t i = 0; i < model.points.size(); ++i) {
    const ColmapPoint& p = read.points[i];
    EXPECT_EQ(p.point_id, model.points[i].id);
    EXPECT_EQ(p.position, model.points[i].xyz);
    EXPECT_EQ(p.color, model.points[i].rgb);
    EXPECT_EQ(p.error_px, model.points[i].error);
    EXPECT_EQ(p.track_length, model.points[i].track.size());
  }
}

class ColmapTest : public testing_util::TempFolderTest {};

// ---------------------------------------------------------------------------------------------
// Reading.

TEST_F(ColmapTest, ReadsTextModel) {
  const TestModel model = MakeModel();
  WriteText(dir_ / "sparse" / "0", model);
  const ColmapModel read = ReadColmapModel(Path("sparse/0"));
  EXPECT_EQ(read.format, "text");
  EXPECT_EQ(read.images_path, (dir_ / "sparse" / "0" / "images.txt").string());
  ExpectMatches(read, model);
  EXPECT_EQ(read.num_observations, 4u);
}

TEST_F(ColmapTest, ReadsBinaryModelAndAgreesWithText) {
  const TestModel model = MakeModel();
  WriteBinary(dir_ / "bin", model);
  WriteText(dir_ / "txt", model);
  const ColmapModel binary = ReadColmapModel(Path("bin"));
  const ColmapModel text = ReadColmapModel(Path("txt"));
  EXPECT_EQ(binary.format, "binary");
  ExpectMatches(binary, model);
  ExpectMatches(text, model);
  // The two readers agree bit for bit.
  ASSERT_EQ(binary.images.size(), text.images.size());
  for (size_t i = 0; i < binary.images.size(); ++i) {
    EXPECT_EQ(binary.images[i].cam_from_world.ToMatrix3x4(),
              text.images[i].cam_from_world.ToMatrix3x4());
  }
  EXPECT_EQ(binary.mean_reprojection_error_px, text.mean_reprojection_error_px);
  EXPECT_EQ(binary.num_observations, text.num_observations);
}

TEST_F(ColmapTest, PrefersBinaryWhenBothExist) {
  TestModel model = MakeModel();
  WriteBinary(dir_ / "m", model);
  model.images.pop_back();
  WriteText(dir_ / "m", model);
  const ColmapModel read = ReadColmapModel(Path("m"));
  EXPECT_EQ(read.format, "binary");
  EXPECT_EQ(read.images.size(), 3u);
  // An incomplete binary set falls back to a complete text set (as COLMAP does).
  fs::remove(dir_ / "m" / "points3D.bin");
  EXPECT_EQ(ReadColmapModel(Path("m")).format, "text");
}

TEST_F(ColmapTest, MeanReprojectionErrorIsColmaps) {
  // Reconstruction::ComputeMeanReprojectionError: the mean of the per-point errors over the
  // points that have one (error != -1), not weighted by track length.
  TestModel model = MakeModel();
  model.points[0].error = 0.5;   // track 2
  model.points[1].error = 1.5;   // track 1
  model.points[1].track = {{5, 2}, {9, 0}, {2, 0}, {5, 1}};
  model.points[2].error = -1.0;  // no error: left out
  WriteBinary(dir_ / "m", model);
  const ColmapModel read = ReadColmapModel(Path("m"));
  EXPECT_DOUBLE_EQ(read.mean_reprojection_error_px, 1.0);  // (0.5 + 1.5) / 2, not 7 / 6
  model.points.clear();
  WriteBinary(dir_ / "empty", model);
  EXPECT_EQ(ReadColmapModel(Path("empty")).mean_reprojection_error_px, 0.0);
}

TEST_F(ColmapTest, MissingFilesAreNamed) {
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("nowhere")); }),
              HasSubstr("nowhere: COLMAP model folder does not exist"));
  const TestModel model = MakeModel();
  WriteBinary(dir_ / "sparse" / "0", model);
  const std::string error = ErrorOf([&] { ReadColmapModel(Path("sparse")); });
  EXPECT_THAT(error, HasSubstr("not a COLMAP sparse model"));
  EXPECT_THAT(error, HasSubstr("found none"));
  EXPECT_THAT(error, HasSubstr("numbered subfolder: " + Path("sparse/0")));
  fs::remove(dir_ / "sparse" / "0" / "images.bin");
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("sparse/0")); }),
              HasSubstr("(found cameras.bin, points3D.bin)"));
}

// Every truncation of every binary file fails with a message naming the file (and never crashes
// or allocates by a garbage count); a few are checked for the field named.
TEST_F(ColmapTest, TruncatedBinaryFilesAreRefused) {
  const TestModel model = MakeModel();
  const std::pair<const char*, std::string> files[] = {{"cameras.bin", CamerasBinary(model)},
                                                       {"images.bin", ImagesBinary(model)},
                                                       {"points3D.bin", PointsBinary(model)}};
  for (const auto& [name, bytes] : files) {
    for (size_t size = 0; size < bytes.size(); ++size) {
      WriteBinary(dir_ / "m", model);
      WriteFile(dir_ / "m" / name, bytes.substr(0, size));
      const std::string error = ErrorOf([&] { ReadColmapModel(Path("m")); });
      EXPECT_THAT(error, HasSubstr(Path("m/") + name)) << size;
    }
  }
  // Cuts inside the last entry (earlier cuts fail the count check first): in the FOV camera's
  // third parameter, and in the last image's name.
  TestModel first_entries = model;
  first_entries.cameras.pop_back();
  first_entries.images.pop_back();
  WriteBinary(dir_ / "m", model);
  const std::string cameras = CamerasBinary(model);
  WriteFile(dir_ / "m" / "cameras.bin",
            cameras.substr(0, CamerasBinary(first_entries).size() + 24 + 8 * 2 + 4));
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("cameras.bin: camera 3 of 4 (id 12): params[2]: file ends early (needs "
                        "8 bytes at offset"));
  WriteBinary(dir_ / "m", model);
  const std::string images = ImagesBinary(model);
  WriteFile(dir_ / "m" / "images.bin",
            images.substr(0, ImagesBinary(first_entries).size() + 4 + 56 + 4 + 3));
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: image 2 of 3 (id 9): name: file ends before"));
  // Trailing bytes.
  WriteFile(dir_ / "m" / "images.bin", images + "xyz");
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: 3 unexpected bytes after the last entry"));
}

TEST_F(ColmapTest, GarbageBinaryFilesAreRefused) {
  const TestModel model = MakeModel();
  // A count far beyond the file: refused before allocating.
  WriteBinary(dir_ / "m", model);
  std::string points = PointsBinary(model);
  for (int i = 0; i < 8; ++i) points[i] = static_cast<char>(0xff);
  WriteFile(dir_ / "m" / "points3D.bin", points);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("points3D.bin: number of points: 18446744073709551615 entries"));
  // A huge num_points2D inside an image.
  WriteBinary(dir_ / "m", model);
  std::string images = ImagesBinary(model);
  const size_t num_points_at = 8 + 4 + 56 + 4 + model.images[0].name.size() + 1;
  for (int i = 0; i < 8; ++i) images[num_points_at + i] = static_cast<char>(0x7f);
  WriteFile(dir_ / "m" / "images.bin", images);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: image 0 of 3 (id 5): num_points2D:"));
  // Random bytes: an error, never a crash.
  std::mt19937 random(7);
  for (int trial = 0; trial < 200; ++trial) {
    WriteBinary(dir_ / "m", model);
    std::string bytes(random() % 300, '\0');
    for (char& c : bytes) c = static_cast<char>(random() & 0xff);
    // Small counts so that the reader gets into the entries.
    if (bytes.size() >= 8) {
      bytes[0] = static_cast<char>(random() % 4);
      for (int i = 1; i < 8; ++i) bytes[i] = 0;
    }
    const char* name = trial % 3 == 0 ? "cameras.bin" : trial % 3 == 1 ? "images.bin"
                                                                         : "points3D.bin";
    WriteFile(dir_ / "m" / name, bytes);
    try {
      ReadColmapModel(Path("m"));
    } catch (const std::invalid_argument& error) {
      EXPECT_THAT(error.what(), HasSubstr(Path("m/")));
    }
  }
  // Unknown model id, zero quaternion, unknown camera, non-finite values, bad sizes.
  TestModel bad = model;
  bad.cameras[1].model_id = 42;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("cameras.bin: camera 1 of 4 (id 7): model_id: unknown COLMAP camera "
                        "model id 42"));
  bad = model;
  bad.images[2].qvec = {0, 0, 0, 0};
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: image 2 of 3 (id 9): QW..QZ: zero quaternion"));
  bad = model;
  bad.images[1].tvec[1] = NAN;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: image 1 of 3 (id 2): TX..TZ: is not finite"));
  bad = model;
  bad.images[0].camera_id = 99;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("images.bin: image 5 (frames/b.png): camera_id: camera 99 is not in"));
  bad = model;
  bad.points[1].xyz.y = INFINITY;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("points3D.bin: point 1 of 3 (id 101): xyz: is not finite"));
  bad = model;
  bad.cameras[0].height = 0;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("cameras.bin: camera 0 of 4 (id 1): height: must be a whole number"));
  bad = model;
  bad.images[1].name = bad.images[0].name;
  WriteBinary(dir_ / "m", bad);
  EXPECT_THAT(ErrorOf([&] { ReadColmapModel(Path("m")); }),
              HasSubstr("image 2 (frames/b.png): name: listed twice"));
}

// Replaces line `line` (1-based) of a text file.
void ReplaceLine(const fs::path& path, int line, const std::string& text) {
  std::ifstream in(path);
  std::string all, current;
  for (int i = 1; std::getline(in, current); ++i) all += (i == line ? text : current) + "\n";
  in.close();
  WriteFile(path, all);
}

TEST_F(ColmapTest, BadTextLinesAreNamed) {
  const TestModel model = MakeModel();
  const fs::path folder = dir_ / "m";
  auto error_with = [&](const char* file, int line, const std::string& text) {
    WriteText(folder, model);
    ReplaceLine(folder / file, line, text);
    return ErrorOf([&] { ReadColmapModel(folder.string()); });
  };
  // cameras.txt: 3 comment lines, then cameras 1, 7, 3, 12 on lines 4..7.
  EXPECT_THAT(error_with("cameras.txt", 5, "7 OPENCV 64 48 71 70 31 24 -0.05 0.0x1 0 0"),
              HasSubstr((folder / "cameras.txt").string() +
                        ": line 5: camera 7: PARAMS[5]: \"0.0x1\" is not a number"));
  EXPECT_THAT(error_with("cameras.txt", 4, "1 SIMPLE_PINHOLE 64 48 70 32"),
              HasSubstr("line 4: camera 1: PARAMS: model SIMPLE_PINHOLE has 3 parameters, the "
                        "line gives 2"));
  EXPECT_THAT(error_with("cameras.txt", 4, "1 PINHOLE_PLUS 64 48 70 32 24"),
              HasSubstr("line 4: camera 1: MODEL: unknown COLMAP camera model \"PINHOLE_PLUS\""));
  EXPECT_THAT(error_with("cameras.txt", 4, "1 SIMPLE_PINHOLE -64 48 70 32 24"),
              HasSubstr("line 4: camera 1: WIDTH: \"-64\" is not a whole number"));
  EXPECT_THAT(error_with("cameras.txt", 4, "1 SIMPLE_PINHOLE 64 48 nan 32 24"),
              HasSubstr("line 4: camera 1: PARAMS[0]: \"nan\" is not finite"));
  EXPECT_THAT(error_with("cameras.txt", 6, "7 PINHOLE 64 48 70 70 32 24"),
              HasSubstr("camera 7: camera_id: listed twice"));
  // images.txt: 3 comment lines, then image 5 on lines 4-5, image 2 on 6-7, image 9 on 8-9.
  EXPECT_THAT(error_with("images.txt", 6, "2 0 0 0 0 1 2 3 1 a.png"),
              HasSubstr((folder / "images.txt").string() +
                        ": line 6: image 2: QW..QZ: zero quaternion"));
  EXPECT_THAT(error_with("images.txt", 6, "2 1 0 0 0 1 2 3 5 a.png"),
              HasSubstr("image 2 (a.png): camera_id: camera 5 is not in " +
                        (folder / "cameras.txt").string()));
  EXPECT_THAT(error_with("images.txt", 6, "2 1 0 0 0 1 2 3 1"),
              HasSubstr("line 6: image 2: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"));
  EXPECT_THAT(error_with("images.txt", 6, "2 1 0 0 0 1 inf 3 1 a.png"),
              HasSubstr("line 6: image 2: TY: \"inf\" is not finite"));
  EXPECT_THAT(error_with("images.txt", 5, "1.5 2.5 100 10.25 3"),
              HasSubstr("line 5: image 5: POINTS2D: expected X Y POINT3D_ID triples, got 5"));
  EXPECT_THAT(error_with("images.txt", 5, "1.5 2.5 100 10.25 3 -2"),
              HasSubstr("line 5: image 5: POINTS2D[1].POINT3D_ID: \"-2\" is not a whole number"));
  // points3D.txt: 2 comment lines, then points on lines 3..5.
  EXPECT_THAT(error_with("points3D.txt", 4, "101 -3 0.0625 8 1 2 3 1.5 5"),
              HasSubstr((folder / "points3D.txt").string() +
                        ": line 4: point 101: expected POINT3D_ID X Y Z R G B ERROR"));
  EXPECT_THAT(error_with("points3D.txt", 4, "101 -3 0.0625 8 1 256 3 1.5 5 2"),
              HasSubstr("line 4: point 101: G: \"256\" is not a whole number in [0, 255]"));
  EXPECT_THAT(error_with("points3D.txt", 5, "100 0.1 0.2 0.3 9 9 9 -1 9 1"),
              HasSubstr("point 100: point3D_id: listed twice"));
}

TEST_F(ColmapTest, TextDetails) {
  // Windows line ends, tabs, and a last image without its points line all read.
  const fs::path folder = dir_ / "m";
  WriteFile(folder / "cameras.txt", "# c\r\n\r\n1\tPINHOLE 10 8 9 9 5 4\r\n");
  WriteFile(folder / "images.txt", "3 1 0 0 0 1 2 3 1 x.png\r\n1.5 2.5 -1\r\n"
                                   "4 1 0 0 0 1 2 3 1 y.png");
  WriteFile(folder / "points3D.txt", "");
  const ColmapModel model = ReadColmapModel(folder.string());
  ASSERT_EQ(model.cameras.size(), 1u);
  EXPECT_EQ(model.cameras[0].params, (std::vector<double>{9, 9, 5, 4}));
  ASSERT_EQ(model.images.size(), 2u);
  EXPECT_EQ(model.images[0].name, "x.png");
  EXPECT_EQ(model.images[0].num_points2d, 1u);
  EXPECT_EQ(model.images[0].num_observations, 0u);
  EXPECT_EQ(model.images[1].name, "y.png");
  EXPECT_EQ(model.images[1].num_points2d, 0u);
  EXPECT_TRUE(model.points.empty());
}

// ---------------------------------------------------------------------------------------------
// Cameras: aos lenses against COLMAP's model equations (src/colmap/sensor/models.h), written out.

// COLMAP's ImgFromCam for the perspective models with radial-tangential distortion.
Vec2d ColmapPerspective(const ColmapCamera& camera, const Vec3d& p) {
  const std::vector<double>& q = camera.params;
  double fx, fy, cx, cy, k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
  if (camera.model == "SIMPLE_RADIAL" || camera.model == "RADIAL") {
    fx = fy = q[0];
    cx = q[1];
    cy = q[2];
    k1 = q[3];
    if (camera.model == "RADIAL") k2 = q[4];
  } else {  // OPENCV, FULL_OPENCV
    fx = q[0], fy = q[1], cx = q[2], cy = q[3], k1 = q[4], k2 = q[5], p1 = q[6], p2 = q[7];
    if (camera.model == "FULL_OPENCV") k3 = q[8];  // k4..k6 = 0 here
  }
  const double u = p.x / p.z, v = p.y / p.z;
  const double u2 = u * u, uv = u * v, v2 = v * v, r2 = u2 + v2;
  const double radial = k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
  const double du = u * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2);
  const double dv = v * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2);
  return Vec2d(fx * (u + du) + cx, fy * (v + dv) + cy);
}

// COLMAP's ImgFromCam for the fisheye models: FisheyeFromNormal (theta = atan(r)), then the
// radial distortion in theta, then the focal lengths.
Vec2d ColmapFisheye(const ColmapCamera& camera, const Vec3d& p) {
  const std::vector<double>& q = camera.params;
  double fx, fy, cx, cy, k[4] = {0, 0, 0, 0};
  if (camera.model == "OPENCV_FISHEYE") {
    fx = q[0], fy = q[1], cx = q[2], cy = q[3];
    for (int i = 0; i < 4; ++i) k[i] = q[4 + i];
  } else {  // SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE
    fx = fy = q[0];
    cx = q[1];
    cy = q[2];
    k[0] = q[3];
    if (camera.model == "RADIAL_FISHEYE") k[1] = q[4];
  }
  double uu = p.x / p.z, vv = p.y / p.z;
  const double r = std::sqrt(uu * uu + vv * vv);
  if (r > 2.220446049250313e-16) {
    const double theta = std::atan(r);
    uu *= theta / r;
    vv *= theta / r;
  }
  const double t2 = uu * uu + vv * vv, t4 = t2 * t2, t6 = t4 * t2, t8 = t4 * t4;
  const double radial = k[0] * t2 + k[1] * t4 + k[2] * t6 + k[3] * t8;
  return Vec2d(fx * (uu + uu * radial) + cx, fy * (vv + vv * radial) + cy);
}

// Points in front of the camera up to `max_theta` off-axis, at several depths.
std::vector<Vec3d> FieldPoints(double max_theta) {
  std::vector<Vec3d> points{Vec3d(0, 0, 3)};
  for (int i = 1; i <= 12; ++i) {
    const double theta = max_theta * i / 12;
    for (int j = 0; j < 16; ++j) {
      const double phi = 2 * kPi * (j + 0.3) / 16;
      const double depth = 0.5 + 0.7 * j;
      points.push_back(depth * Vec3d(std::sin(theta) * std::cos(phi),
                                     std::sin(theta) * std::sin(phi), std::cos(theta)));
    }
  }
  return points;
}

TEST(ColmapCameras, LensesProjectAsColmap) {
  const ColmapCamera perspective[] = {
      {1, "SIMPLE_RADIAL", 640, 480, {500.5, 320.25, 239.75, -0.08}},
      {2, "RADIAL", 640, 480, {510.0, 321.5, 238.5, -0.09, 0.02}},
      {3, "OPENCV", 640, 480, {505.0, 498.5, 318.0, 242.0, -0.1, 0.03, 0.0012, -0.0008}},
      {4, "FULL_OPENCV", 640, 480,
       {505.0, 498.5, 318.0, 242.0, -0.1, 0.03, 0.0012, -0.0008, -0.004, 0, 0, 0}},
  };
  for (const ColmapCamera& camera : perspective) {
    const LensCamera lens = LensFromColmapCamera(camera, "cameras.txt");
    EXPECT_EQ(lens.model, LensModel::kRadTan) << camera.model;
    EXPECT_EQ(lens.width, 640);
    int projected = 0;
    for (const Vec3d& point : FieldPoints(0.6)) {
      Vec2d pixel;
      ASSERT_TRUE(lens.Project(point, &pixel)) << camera.model;
      const Vec2d expected = ColmapPerspective(camera, point);
      // Same polynomial evaluated in another order: rounding only (~1e-13 px at 500 px).
      EXPECT_NEAR(pixel.x, expected.x, 1e-9) << camera.model;
      EXPECT_NEAR(pixel.y, expected.y, 1e-9) << camera.model;
      ++projected;
    }
    EXPECT_GT(projected, 100);
  }
  const ColmapCamera fisheyes[] = {
      {5, "OPENCV_FISHEYE", 800, 800, {250.5, 251.0, 400.25, 399.5, 0.03, -0.01, 0.002, -0.0003}},
      {6, "SIMPLE_RADIAL_FISHEYE", 800, 800, {252.0, 401.0, 398.0, 0.025}},
      {7, "RADIAL_FISHEYE", 800, 800, {249.0, 399.0, 402.0, 0.02, -0.004}},
  };
  for (const ColmapCamera& camera : fisheyes) {
    const LensCamera lens = LensFromColmapCamera(camera, "cameras.txt");
    EXPECT_EQ(lens.model, LensModel::kFisheye) << camera.model;
    for (const Vec3d& point : FieldPoints(1.4)) {  // up to 80 degrees off-axis
      Vec2d pixel;
      ASSERT_TRUE(lens.Project(point, &pixel)) << camera.model;
      const Vec2d expected = ColmapFisheye(camera, point);
      EXPECT_NEAR(pixel.x, expected.x, 1e-9) << camera.model;
      EXPECT_NEAR(pixel.y, expected.y, 1e-9) << camera.model;
    }
  }
}

TEST(ColmapCameras, PinholeModelsAndZeroDistortion) {
  const LensCamera simple = LensFromColmapCamera({1, "SIMPLE_PINHOLE", 64, 48, {70, 32, 24}}, "c");
  EXPECT_EQ(simple.model, LensModel::kPinhole);
  EXPECT_EQ(simple.fx, 70.0);
  EXPECT_EQ(simple.fy, 70.0);
  // COLMAP's pixel centres are at +0.5, as aos's: the principal point is taken unchanged.
  EXPECT_EQ(simple.cx, 32.0);
  EXPECT_EQ(simple.cy, 24.0);
  const LensCamera pinhole =
      LensFromColmapCamera({2, "PINHOLE", 64, 48, {70, 71, 31.5, 24.5}}, "c");
  EXPECT_EQ(pinhole.model, LensModel::kPinhole);
  EXPECT_EQ(pinhole.fy, 71.0);
  EXPECT_EQ(pinhole.cx, 31.5);
  const LensCamera opencv =
      LensFromColmapCamera({3, "OPENCV", 64, 48, {70, 71, 31.5, 24.5, 0, 0, 0, 0}}, "c");
  EXPECT_EQ(opencv.model, LensModel::kPinhole);
  // A fisheye stays a fisheye without distortion terms (the equidistant projection).
  const LensCamera fisheye =
      LensFromColmapCamera({4, "OPENCV_FISHEYE", 64, 48, {70, 71, 31.5, 24.5, 0, 0, 0, 0}}, "c");
  EXPECT_EQ(fisheye.model, LensModel::kFisheye);
  EXPECT_EQ(LensFromColmapCamera({5, "FISHEYE", 64, 48, {30, 31, 32, 24}}, "c").model,
            LensModel::kFisheye);
  EXPECT_EQ(LensFromColmapCamera({6, "SIMPLE_FISHEYE", 64, 48, {30, 32, 24}}, "c").fy, 30.0);
}

TEST(ColmapCameras, UnsupportedModelsAreRefused) {
  EXPECT_THAT(ErrorOf([] {
                LensFromColmapCamera({12, "FOV", 64, 48, {60, 61, 32, 24, 0.9}},
                                     "sparse/cameras.bin");
              }),
              HasSubstr("sparse/cameras.bin: camera 12 (FOV): model: COLMAP's FOV model has no "
                        "aos lens"));
  EXPECT_THAT(ErrorOf([] {
                LensFromColmapCamera({4, "THIN_PRISM_FISHEYE", 64, 48,
                                      {60, 61, 32, 24, 0, 0, 0, 0, 0, 0, 0, 0}},
                                     "cameras.txt");
              }),
              HasSubstr("cameras.txt: camera 4 (THIN_PRISM_FISHEYE): model:"));
  EXPECT_THAT(ErrorOf([] {
                LensFromColmapCamera({8, "FULL_OPENCV", 64, 48,
                                      {60, 61, 32, 24, -0.1, 0.01, 0, 0, 0.001, 0, 0.02, 0}},
                                     "cameras.txt");
              }),
              HasSubstr("cameras.txt: camera 8 (FULL_OPENCV): params[10] (k5 = 0.02): the "
                        "rational radial distortion"));
  EXPECT_THAT(ErrorOf([] { LensFromColmapCamera({9, "PINHOLE", 64, 48, {60, 32, 24}}, "c"); }),
              HasSubstr("c: camera 9 (PINHOLE): params: the model has 4 parameters, got 3"));
  EXPECT_THAT(ErrorOf([] { LensFromColmapCamera({9, "PINHOLE", 64, 48, {-60, 60, 32, 24}}, "c"); }),
              HasSubstr("c: camera 9 (PINHOLE): fx/fy: must be > 0"));
}

// ---------------------------------------------------------------------------------------------
// Import into a light field.

Image Frame(int width, int height, int seed) {
  Image image(width, height, 3, PixelType::kU8, 0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) {
        image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(x * 13 + y * 7 + c + seed);
      }
    }
  }
  return image;
}

class ColmapImportTest : public testing_util::TempFolderTest {
 protected:
  void SetUp() override {
    TempFolderTest::SetUp();
    model_ = MakeModel();
    model_.cameras[3] = {12, 2, "SIMPLE_RADIAL", 64, 48, {60, 32, 24, -0.02}};  // not FOV
    model_.images[1].name = "a.png";
    WriteBinary(dir_ / "sparse", model_);
    const fs::path images = dir_ / "images";
    fs::create_directories(images / "frames");
    WriteImage((images / "frames" / "b.png").string(), Frame(64, 48, 1));
    WriteImage((images / "a.png").string(), Frame(64, 48, 2));
    WriteImage((images / "c.png").string(), Frame(80, 60, 3));
    WriteImage((images / "d.PNG").string(), Frame(64, 48, 4));           // not registered
    WriteImage((images / "frames" / "e.tif").string(), Frame(64, 48, 5));  // not registered
    WriteFile(images / "notes.txt", "not a frame");
  }
  TestModel model_;
};

TEST_F(ColmapImportTest, BuildsViewsAndListsUnregisteredFrames) {
  const ColmapModel model = ReadColmapModel(Path("sparse"));
  for (bool load_images : {false, true}) {
    ColmapImportOptions options;
    options.load_images = load_images;
    options.num_threads = 2;
    const ColmapImport import = ImportColmapModel(model, Path("images"), options);
    EXPECT_EQ(import.registered, (std::vector<std::string>{"a.png", "c.png", "frames/b.png"}));
    EXPECT_EQ(import.unregistered, (std::vector<std::string>{"d.PNG", "frames/e.tif"}));
    const std::vector<View>& views = import.light_field.views;
    ASSERT_EQ(views.size(), 3u);
    EXPECT_EQ(import.light_field.origin, Vec3d(0.0));
    // a.png: image 2, SIMPLE_PINHOLE camera 1.
    EXPECT_EQ(views[0].name, "a.png");
    EXPECT_EQ(views[0].image_path, (dir_ / "images" / "a.png").string());
    EXPECT_EQ(views[0].camera.model, LensModel::kPinhole);
    EXPECT_EQ(views[0].camera.fx, 70.5);
    EXPECT_EQ(views[0].camera.cx, 32.25);
    EXPECT_EQ(views[0].cam_from_world.ToMatrix3x4(), model.images[1].cam_from_world.ToMatrix3x4());
    // c.png: OPENCV_FISHEYE camera 3 -> a fisheye lens whose intrinsics equal the camera's.
    EXPECT_EQ(views[1].camera.model, LensModel::kFisheye);
    EXPECT_EQ(views[1].camera.width, 80);
    EXPECT_EQ(views[1].camera.fy, 40.3);
    EXPECT_EQ(views[1].camera.fy, 40.3);
    EXPECT_EQ(views[1].camera.distortion[3], -0.0004);
    // frames/b.png: OPENCV camera 7 -> radtan.
    EXPECT_EQ(views[2].camera.model, LensModel::kRadTan);
    EXPECT_EQ(views[2].camera.distortion[2], 0.001);
    EXPECT_EQ(views[2].image_path, (dir_ / "images" / "frames" / "b.png").string());
    for (const View& view : views) {
      EXPECT_EQ(view.image.empty(), !load_images);
      if (load_images) {
        EXPECT_EQ(view.image.border(), 1);
        EXPECT_EQ(view.image.width(), view.camera.width);
      }
    }
    if (load_images) {
      EXPECT_EQ(views[0].image.Value(5, 3, 1), static_cast<double>(5 * 13 + 3 * 7 + 1 + 2));
      EXPECT_NO_THROW(CheckLightField(import.light_field));
    }
  }
}

TEST_F(ColmapImportTest, CaptureTimesOrderTheViewsWithAWarning) {
  // c.png was taken first, then frames/b.png, then a.png: the views follow capture time.
  const struct {
    const char* name;
    int width, height;
    const char* time;
  } frames[] = {{"c.png", 80, 60, "2026:06:01 10:00:00"},
                {"frames/b.png", 64, 48, "2026:06:01 10:00:01"},
                {"a.png", 64, 48, "2026:06:01 10:00:02"}};
  for (const auto& frame : frames) {
    ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(Path("images/") + frame.name, frame.width,
                                                  frame.height, 48.0, 15.0, 300.0, frame.time));
  }
  ASSERT_TRUE(ReadCaptureTime(Path("images/c.png")).has_value()) << "PNG keeps no EXIF here";
  const ColmapImport import = ImportColmapModel(ReadColmapModel(Path("sparse")), Path("images"));
  EXPECT_EQ(import.order, "time");
  EXPECT_EQ(import.time_source, "EXIF DateTimeOriginal");
  EXPECT_EQ(import.registered, (std::vector<std::string>{"c.png", "frames/b.png", "a.png"}));
  EXPECT_EQ(import.light_field.views[0].name, "c.png");
  ASSERT_EQ(import.warnings.size(), 1u);
  EXPECT_THAT(import.warnings[0], HasSubstr("c.png (at +0 s) was taken before a.png (at +2 s)"));
  // One frame without a time: name order, and a warning naming it.
  ASSERT_TRUE(testing_util::WriteGpsTaggedFrame(Path("images/a.png"), 64, 48, 48.0, 15.0, 300.0));
  const ColmapImport by_name = ImportColmapModel(ReadColmapModel(Path("sparse")), Path("images"));
  EXPECT_EQ(by_name.order, "name");
  EXPECT_EQ(by_name.registered, (std::vector<std::string>{"a.png", "c.png", "frames/b.png"}));
  ASSERT_EQ(by_name.warnings.size(), 1u);
  EXPECT_THAT(by_name.warnings[0], HasSubstr("1 of 3 frames have no capture time"));
}

TEST_F(ColmapImportTest, ListsFrameFiles) {
  EXPECT_EQ(ListFrameFiles(Path("images")),
            (std::vector<std::string>{"a.png", "c.png", "d.PNG", "frames/b.png", "frames/e.tif"}));
  EXPECT_THAT(ErrorOf([&] { ListFrameFiles(Path("no_images")); }),
              HasSubstr("no_images: not a folder"));
}

TEST_F(ColmapImportTest, BadFramesAreNamed) {
  ColmapModel model = ReadColmapModel(Path("sparse"));
  const std::string images_path = Path("sparse/images.bin");
  WriteImage(Path("images/c.png"), Frame(64, 48, 3));
  for (bool load_images : {false, true}) {
    ColmapImportOptions options;
    options.load_images = load_images;
    EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("images"), options); }),
                HasSubstr(images_path + ": image 9 (c.png): frame " + Path("images/c.png") +
                          " is 64x48 but its COLMAP camera in " + Path("sparse/cameras.bin") +
                          " says 80x60"));
  }
  fs::remove(Path("images/c.png"));
  EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("images")); }),
              HasSubstr(images_path + ": image 9 (c.png): frame \"" + Path("images/c.png") +
                        "\" not found in images_dir"));
  EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("no_images")); }),
              HasSubstr("no_images: images_dir: folder does not exist"));
  model.cameras[0].model = "FOV";
  model.cameras[0].params = {60, 61, 32, 24, 0.9};
  EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("images")); }),
              HasSubstr(Path("sparse/cameras.bin") + ": camera 1 (FOV): model:"));
  ColmapImportOptions bad_threads;
  bad_threads.num_threads = 0;
  EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("images"), bad_threads); }),
              HasSubstr("num_threads: must be in [1, 1024] or -1"));
  model.images.clear();
  EXPECT_THAT(ErrorOf([&] { ImportColmapModel(model, Path("images")); }),
              HasSubstr("the model has no registered images"));
}

// ---------------------------------------------------------------------------------------------
// Similarity transforms.

Sim3d RandomSim(std::mt19937_64& random, double offset_scale) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Sim3d sim;
  sim.scale = std::exp(2.0 * unit(random));  // 0.14 .. 7.4
  sim.rotation = AxisAngle(Vec3d(unit(random), unit(random), unit(random)), kPi * unit(random));
  sim.translation = Vec3d(unit(random), unit(random), unit(random)) * offset_scale;
  return sim;
}

std::vector<Vec3d> RandomPoints(std::mt19937_64& random, int n, double extent) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<Vec3d> points;
  for (int i = 0; i < n; ++i) {
    points.push_back(extent * Vec3d(unit(random), unit(random), 0.2 * unit(random)));
  }
  return points;
}

void ExpectSimNear(const Sim3d& a, const Sim3d& b, double relative) {
  EXPECT_NEAR(a.scale, b.scale, relative * b.scale);
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) EXPECT_NEAR(a.rotation[c][r], b.rotation[c][r], relative);
  }
  const double t = std::max(1.0, glm::length(b.translation));
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(a.translation[k], b.translation[k], relative * t);
}

TEST(Similarity, RecoversExactTransforms) {
  std::mt19937_64 random(1234);
  // Model-sized source frames mapped to local, then UTM-sized (easting 5e5, northing 5e6) targets.
  const Vec3d utm(512345.678, 5345678.901, 412.5);
  for (int trial = 0; trial < 40; ++trial) {
    const bool geo = trial % 2 == 1;
    Sim3d truth = RandomSim(random, 100.0);
    if (geo) truth.translation += utm;
    const std::vector<Vec3d> src = RandomPoints(random, 3 + trial, 20.0);
    std::vector<Vec3d> dst;
    for (const Vec3d& p : src) dst.push_back(truth * p);
    const SimilarityResult fit = EstimateSimilarity(src, dst, "test");
    // Exact data: agreement to rounding. The UTM targets carry ~1e-9 m of rounding each, over a
    // spread >= a few metres: relative 1e-9 holds with margin.
    ExpectSimNear(fit.dst_from_src, truth, 1e-9);
    EXPECT_LT(fit.rms_residual, geo ? 1e-8 : 1e-10) << trial;
    EXPECT_NEAR(glm::determinant(fit.dst_from_src.rotation), 1.0, 1e-12);
  }
}

TEST(Similarity, CoplanarPointsAndReflectionCase) {
  // Cameras flown at one altitude: a planar set, where the third singular value is zero and the
  // rotation's handedness comes from det(U) det(V).
  std::mt19937_64 random(99);
  for (int trial = 0; trial < 10; ++trial) {
    const Sim3d truth = RandomSim(random, 1e3);
    std::vector<Vec3d> src = RandomPoints(random, 12, 50.0);
    for (Vec3d& p : src) p.z = 3.0;
    std::vector<Vec3d> dst;
    for (const Vec3d& p : src) dst.push_back(truth * p);
    ExpectSimNear(EstimateSimilarity(src, dst, "test").dst_from_src, truth, 1e-9);
  }
}

TEST(Similarity, NoisyPointsGiveTheExpectedRms) {
  std::mt19937_64 random(5);
  const int n = 3000;
  const double sigma = 0.05;  // metres per axis, GPS-like
  Sim3d truth = RandomSim(random, 100.0);
  truth.translation += Vec3d(612345.0, 5432109.0, 300.0);
  const std::vector<Vec3d> src = RandomPoints(random, n, 200.0);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<Vec3d> dst;
  for (const Vec3d& p : src) {
    dst.push_back(truth * p + Vec3d(noise(random), noise(random), noise(random)));
  }
  const SimilarityResult fit = EstimateSimilarity(src, dst, "test");
  // E[sum of squared residuals] = sigma^2 (3 n - 7); the RMS has a relative spread of about
  // 1 / sqrt(2 (3 n - 7)) = 0.8 %: 4 % is five standard deviations.
  const double expected = sigma * std::sqrt((3.0 * n - 7.0) / n);
  EXPECT_NEAR(fit.rms_residual, expected, 0.04 * expected);
  EXPECT_GT(fit.max_residual, fit.rms_residual);
  // The fit is close to the truth: scale and rotation to ~sigma / extent / sqrt(n).
  EXPECT_NEAR(fit.dst_from_src.scale, truth.scale, 1e-3 * truth.scale);
}

TEST(Similarity, DegenerateSetsAreRefused) {
  const std::vector<Vec3d> two = {Vec3d(0, 0, 0), Vec3d(1, 0, 0)};
  EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(two, two, "geo-reference"); }),
              HasSubstr("geo-reference: a similarity transform needs at least 3 point pairs "
                        "(got 2)"));
  const std::vector<Vec3d> three = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)};
  EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(three, two, "g"); }),
              HasSubstr("g: got 3 source points but 2 target points"));
  const std::vector<Vec3d> collinear = {Vec3d(1, 2, 3), Vec3d(2, 4, 6), Vec3d(-1, -2, -3),
                                        Vec3d(5, 10, 15)};
  EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(collinear, collinear, "g"); }),
              HasSubstr("g: source points are collinear"));
  const std::vector<Vec3d> coincident(4, Vec3d(512345.0, 5345678.0, 400.0));
  EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(three, std::vector<Vec3d>(coincident.begin(),
                                                                          coincident.begin() + 3),
                                                 "g"); }),
              HasSubstr("g: target points are coincident"));
  std::vector<Vec3d> with_nan = three;
  with_nan[1].y = NAN;
  EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(three, with_nan, "g"); }),
              HasSubstr("g: target point 1 is not finite"));
  // Nearly collinear: a cross of half-lengths 100 and 100 * width has sqrt(lambda2 / lambda1) =
  // width exactly. A third of the threshold is refused; three times it is fitted, the rotation
  // to the rounding the threshold allows (2.2e-16 / width^2 = 2.5e-9 rad).
  for (const double width : {kMinRelativeWidth / 3, 3 * kMinRelativeWidth}) {
    const std::vector<Vec3d> src = {Vec3d(100, 0, 0), Vec3d(-100, 0, 0), Vec3d(0, 100 * width, 0),
                                    Vec3d(0, -100 * width, 0)};
    Sim3d truth;
    truth.scale = 2.0;
    truth.rotation = AxisAngle(Vec3d(0.3, 0.2, 1.0), 0.8);
    truth.translation = Vec3d(10, 20, 30);
    std::vector<Vec3d> dst;
    for (const Vec3d& p : src) dst.push_back(truth * p);
    if (width < kMinRelativeWidth) {
      EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(src, dst, "g"); }),
                  HasSubstr("collinear"));
    } else {
      ExpectSimNear(EstimateSimilarity(src, dst, "g").dst_from_src, truth, 3e-8);
    }
  }
}

TEST(Similarity, TinyBaselinesAtUtmCoordinates) {
  // Target points at a UTM northing (5.3e6 m): the smallest accepted RMS spread is
  // kMinRelativeSpread * 5.3e6 = 5.3 mm. A cluster with twice that spread is fitted (to the
  // precision its coordinates' rounding allows), one with half of it is refused.
  const Vec3d utm(512345.678, 5345678.901, 412.5);
  const double threshold = kMinRelativeSpread * utm.y;
  const std::vector<Vec3d> unit = {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(0, 1, 0),
                                   Vec3d(0, -1, 0), Vec3d(0, 0, 1), Vec3d(0, 0, -1)};
  // RMS distance of `unit` from its centroid is 1: `unit * spread` has RMS spread `spread`.
  for (const double factor : {2.0, 0.5}) {
    const double spread = factor * threshold;
    Sim3d truth;
    truth.scale = spread / 10.0;  // a model in units of 10 / spread
    truth.rotation = AxisAngle(Vec3d(1, -2, 0.5), 2.0);
    truth.translation = utm;
    std::vector<Vec3d> src, dst;
    for (const Vec3d& p : unit) {
      src.push_back(10.0 * p);
      dst.push_back(truth * src.back());
    }
    if (factor > 1.0) {
      const SimilarityResult fit = EstimateSimilarity(src, dst, "g");
      // Coordinates round at ~1e-9 m out of a 1e-2 m spread: ~1e-7 relative.
      ExpectSimNear(fit.dst_from_src, truth, 1e-6);
      EXPECT_LT(fit.rms_residual, 1e-8);
    } else {
      EXPECT_THAT(ErrorOf([&] { EstimateSimilarity(src, dst, "g"); }),
                  HasSubstr("g: target points are coincident: their RMS spread"));
    }
  }
}

TEST(Similarity, TransformsCameraPoses) {
  std::mt19937_64 random(77);
  const PinholeCamera camera{640, 480, 500.0, 505.0, 320.5, 240.25};
  for (int trial = 0; trial < 10; ++trial) {
    Sim3d new_from_old = RandomSim(random, 50.0);
    if (trial % 2) new_from_old.translation += Vec3d(512345.0, 5345678.0, 400.0);
    const Rigid3d cam_from_old =
        LookAt(Vec3d(3.0 * trial, -2.0, 40.0), Vec3d(1.0, 2.0, 0.0), Vec3d(0, 1, 0));
    const Rigid3d cam_from_new = TransformCamFromWorld(new_from_old, cam_from_old);
    EXPECT_FALSE(DescribeInvalidRigid(cam_from_new, 1e-12).has_value());
    // The camera centre maps with the world.
    const Vec3d centre = new_from_old * cam_from_old.Center();
    const Vec3d moved = cam_from_new.Center();
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(moved[k], centre[k], 1e-9 * std::max(1.0, std::abs(centre[k])));
    }
    // A world point and its image project to the same pixel.
    for (const Vec3d& point : {Vec3d(0, 0, 0), Vec3d(4, -3, 1), Vec3d(-6, 5, -2)}) {
      const Vec2d before = camera.Project(cam_from_old * point);
      const Vec2d after = camera.Project(cam_from_new * (new_from_old * point));
      EXPECT_NEAR(after.x, before.x, 1e-6);
      EXPECT_NEAR(after.y, before.y, 1e-6);
      // Camera coordinates scale by s.
      const Vec3d in_cam = cam_from_old * point;
      const Vec3d in_cam_new = cam_from_new * (new_from_old * point);
      EXPECT_NEAR(glm::length(in_cam_new), new_from_old.scale * glm::length(in_cam),
                  1e-9 * (1.0 + glm::length(new_from_old.translation)));
    }
    // Inverse: round trip.
    const Sim3d back = new_from_old.Inverse();
    const Vec3d p(1.25, -7.5, 3.0);
    const Vec3d q = back * (new_from_old * p);
    // Through UTM-sized coordinates (rounding ~1e-9 m) and back with 1 / scale (up to 7.4).
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(q[k], p[k], 1e-7);
  }
  Sim3d zero;
  zero.scale = 0.0;
  EXPECT_THAT(ErrorOf([&] { TransformCamFromWorld(zero, Rigid3d{}); }),
              HasSubstr("scale must be positive"));
}

}  // namespace
}  // namespace aos
