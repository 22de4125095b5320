#include "aos/lightfield/formats.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "temp_folder.h"

#include "aos/image/image_io.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"

namespace aos {
namespace {

namespace fs = std::filesystem;
using testing::HasSubstr;

// A fresh folder per test, removed at the end.
class FormatsTest : public testing_util::TempFolderTest {
 protected:
  void WriteText(const std::string& name, const std::string& text) const {
    fs::create_directories(fs::path(Path(name)).parent_path());
    std::ofstream(Path(name), std::ios::binary) << text;
  }
};

// A deterministic test pattern that uses the whole value range of the type.
Image MakePattern(int width, int height, int channels, PixelType type, int seed) {
  Image image(width, height, channels, type, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const unsigned k = static_cast<unsigned>((x * 7919 + y * 104729 + c * 31 + seed * 977) %
                                                 65536);
        switch (type) {
          case PixelType::kU8: image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(k * 13); break;
          case PixelType::kU16: image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(k * 40503); break;
          case PixelType::kU32: image.At<uint32_t>(x, y)[c] = k; break;
          case PixelType::kF32:
            image.At<float>(x, y)[c] = (static_cast<float>(k) - 30000.0f) / 7.3f;
            break;
        }
      }
    }
  }
  image.FillBorder();
  return image;
}

void ExpectSamePixels(const Image& a, const Image& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  ASSERT_EQ(a.channels(), b.channels());
  ASSERT_EQ(a.type(), b.type());
  int differences = 0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      for (int c = 0; c < a.channels(); ++c) {
        // Bit-exact: compare as doubles, which hold every uint8/uint16/float32 value exactly.
        if (a.Value(x, y, c) != b.Value(x, y, c)) ++differences;
      }
    }
  }
  EXPECT_EQ(differences, 0);
}

void ExpectPoseNear(const Rigid3d& a, const Rigid3d& b, double tolerance) {
  const auto ma = a.ToMatrix3x4();
  const auto mb = b.ToMatrix3x4();
  for (int i = 0; i < 12; ++i) EXPECT_NEAR(ma[i], mb[i], tolerance) << "entry " << i;
}

void ExpectSameCamera(const PinholeCamera& a, const PinholeCamera& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
}

void ExpectSameCamera(const LensCamera& a, const PinholeCamera& b) {
  EXPECT_EQ(a.model, LensModel::kPinhole);
  ExpectSameCamera(a.Pinhole(), b);
}

void ExpectSameCamera(const LensCamera& a, const LensCamera& b) {
  EXPECT_TRUE(a.SameParameters(b));
  EXPECT_EQ(a.theta_max, b.theta_max);
  EXPECT_EQ(a.max_radius, b.max_radius);
}

// Runs `load` and expects std::invalid_argument whose message contains every substring.
void ExpectInvalid(const std::function<void()>& load, std::initializer_list<std::string> parts) {
  try {
    load();
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    for (const std::string& part : parts) EXPECT_THAT(error.what(), HasSubstr(part));
  }
}

LoadOptions Jku(double fov_deg = 50.0) {
  LoadOptions options;
  options.fov_deg = fov_deg;
  return options;
}

LoadOptions HeadersOnly() {
  LoadOptions options;
  options.load_images = false;
  return options;
}

// A light field of three views around a UTM-sized origin; views 0 and 1 share a camera.
LightField MakeLightField(PixelType type, int channels) {
  LightField light_field;
  light_field.origin = Vec3d(5432100.123456, 612345.654321, 301.000000123);
  const PinholeCamera shared{9, 7, 11.123456789012345, 11.25, 4.5, 3.5};
  PinholeCamera other = shared;
  other.cx = 4.25;  // differs in one field only: must not be merged
  const PinholeCamera cameras[3] = {shared, shared, other};
  for (int i = 0; i < 3; ++i) {
    const Rigid3d pose = LookAt(Vec3d(0.1 * i - 3.3, 2.0 / 3.0 + i, 35.0 + i / 7.0),
                                Vec3d(1.0 / 3.0, -0.2, 0.0), Vec3d(0.0, 1.0, 0.0));
    light_field.views.push_back(
        MakeView("v" + std::to_string(i), cameras[i], pose, MakePattern(9, 7, channels, type, i)));
  }
  return light_field;
}

void RoundTrip(const fs::path& dir, PixelType type, int channels, const std::string& extension) {
  const LightField original = MakeLightField(type, channels);
  const std::string path = (dir / "lf.json").string();
  WriteLightFieldOptions write_options;
  write_options.image_extension = extension;
  WriteLightField(path, original, write_options);
  EXPECT_TRUE(fs::is_regular_file(dir / "views" / ("0002" + extension)));

  const LoadResult loaded = LoadLightField(path);
  EXPECT_EQ(loaded.format, "aos");
  EXPECT_TRUE(loaded.notes.empty());
  const LightField& light_field = loaded.light_field;
  // Doubles are written in their shortest round-trip form, so the origin comes back exactly.
  EXPECT_EQ(light_field.origin.x, original.origin.x);
  EXPECT_EQ(light_field.origin.y, original.origin.y);
  EXPECT_EQ(light_field.origin.z, original.origin.z);
  ASSERT_EQ(light_field.views.size(), original.views.size());
  for (size_t i = 0; i < original.views.size(); ++i) {
    SCOPED_TRACE("view " + std::to_string(i));
    const View& view = light_field.views[i];
    EXPECT_EQ(view.name, original.views[i].name);  // kept: "name" beside the image written
    EXPECT_TRUE(fs::equivalent(view.image_path, dir / "views" / ("000" + std::to_string(i) + extension)));
    ExpectSameCamera(view.camera, original.views[i].camera);
    ExpectPoseNear(view.cam_from_world, original.views[i].cam_from_world, 1e-12);
    EXPECT_EQ(view.image.border(), 1);
    ExpectSamePixels(view.image, original.views[i].image);
  }
}

TEST_F(FormatsTest, RoundTripUint8Rgb) { RoundTrip(dir_, PixelType::kU8, 3, ".png"); }
TEST_F(FormatsTest, RoundTripUint16) { RoundTrip(dir_, PixelType::kU16, 1, ".png"); }
TEST_F(FormatsTest, RoundTripFloatTiff) { RoundTrip(dir_, PixelType::kF32, 1, ".tif"); }
TEST_F(FormatsTest, RoundTripFloatExr) { RoundTrip(dir_, PixelType::kF32, 2, ".exr"); }

// Frames decoded one by one into a poses-only light field are the loader's frames; dropping
// them keeps the poses; a frame that became unreadable is named with its file.
TEST_F(FormatsTest, LoadViewImagesDecodesOnlyTheGivenViews) {
  const LightField original = MakeLightField(PixelType::kU8, 3);
  const std::string path = Path("lf.json");
  WriteLightField(path, original);
  const LightField full = LoadLightField(path).light_field;
  LightField poses = LoadLightField(path, HeadersOnly()).light_field;
  LoadViewImages(poses, {2, 0});
  ExpectSamePixels(poses.views[0].image, full.views[0].image);
  ExpectSamePixels(poses.views[2].image, full.views[2].image);
  EXPECT_TRUE(poses.views[1].image.empty());
  EXPECT_EQ(poses.views[2].image.border(), full.views[2].image.border());
  DropViewImages(poses, {0});
  EXPECT_TRUE(poses.views[0].image.empty());
  EXPECT_FALSE(poses.views[2].image.empty());
  ExpectInvalid([&] { LoadViewImages(poses, {3}); }, {"indices: 3 is not a view"});
  // Grey frames, as the loader makes them.
  LoadOptions grey;
  grey.grey = true;
  LoadViewImages(poses, {2}, grey);
  EXPECT_EQ(poses.views[2].image.channels(), 1);
  ExpectSamePixels(poses.views[2].image, LoadLightField(path, grey).light_field.views[2].image);
  std::ofstream(poses.views[1].image_path, std::ios::binary) << "not an image";
  ExpectInvalid([&] { LoadViewImages(poses, {1}); }, {"view 1 (", "0001.png"});
}

TEST_F(FormatsTest, WriteSharesIdenticalCamerasOnly) {
  WriteLightField(Path("lf.json"), MakeLightField(PixelType::kU8, 1));
  const std::string text = ReadTextFile(Path("lf.json"));
  EXPECT_THAT(text, HasSubstr("\"format\": \"aos-lightfield\""));
  EXPECT_THAT(text, HasSubstr("\"cam0\""));
  EXPECT_THAT(text, HasSubstr("\"cam1\""));
  EXPECT_THAT(text, testing::Not(HasSubstr("\"cam2\"")));
  // The origin is written with all its digits.
  EXPECT_THAT(text, HasSubstr("5432100.123456"));
}

TEST_F(FormatsTest, HeadersOnlyKeepsImagesEmpty) {
  const LightField original = MakeLightField(PixelType::kU16, 1);
  WriteLightField(Path("lf.json"), original);
  const LoadResult loaded = LoadLightField(Path("lf.json"), HeadersOnly());
  ASSERT_EQ(loaded.light_field.views.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const View& view = loaded.light_field.views[i];
    EXPECT_TRUE(view.image.empty());
    ExpectSameCamera(view.camera, original.views[i].camera);
    ExpectPoseNear(view.cam_from_world, original.views[i].cam_from_world, 1e-12);
  }
}

TEST_F(FormatsTest, RewriteReferencesSourceImagesRelatively) {
  WriteLightField(Path("lf.json"), MakeLightField(PixelType::kU8, 1));
  const LoadResult first = LoadLightField(Path("lf.json"), HeadersOnly());
  fs::create_directories(dir_ / "sub");
  WriteLightField(Path("sub/copy.json"), first.light_field);
  EXPECT_FALSE(fs::exists(dir_ / "sub" / "views"));  // referenced, not rewritten
  EXPECT_THAT(ReadTextFile(Path("sub/copy.json")), HasSubstr("\"../views/0001.png\""));
  const LoadResult second = LoadLightField(Path("sub/copy.json"));
  ASSERT_EQ(second.light_field.views.size(), 3u);
  const Image expected = ReadImage(Path("views/0001.png"), 1);
  ExpectSamePixels(second.light_field.views[1].image, expected);
}

TEST_F(FormatsTest, WriteRefusesToOverwriteSourceImages) {
  WriteLightField(Path("lf.json"), MakeLightField(PixelType::kU8, 1));
  LightField light_field = LoadLightField(Path("lf.json")).light_field;
  // The JSON over a source image.
  ExpectInvalid([&] { WriteLightField(Path("views/0000.png"), light_field); },
                {"views/0000.png", "refusing to overwrite"});
  // View 1 has no source file, so it would be written to views/0001.png, which is now view 0's
  // source.
  light_field.views[0].image_path = Path("views/0001.png");
  light_field.views[1].image_path.clear();
  const std::string before = ReadTextFile(Path("lf.json"));
  ExpectInvalid([&] { WriteLightField(Path("lf.json"), light_field); },
                {"0001.png", "refusing to overwrite"});
  EXPECT_EQ(ReadTextFile(Path("lf.json")), before);  // nothing written
}

TEST_F(FormatsTest, WriteRejectsBadViews) {
  LightField light_field = MakeLightField(PixelType::kU8, 1);
  light_field.views[1].cam_from_world.rotation[0][0] = std::nan("");
  ExpectInvalid([&] { WriteLightField(Path("lf.json"), light_field); },
                {"lf.json", "view 1 (v1)", "cam_from_world"});
  EXPECT_FALSE(fs::exists(Path("lf.json")));
  ExpectInvalid([&] { WriteLightField(Path("lf.json"), LightField{}); }, {"lf.json", "no views"});
  ExpectInvalid([&] { WriteLightField(Path("missing/lf.json"), MakeLightField(PixelType::kU8, 1)); },
                {"missing", "does not exist"});
}

// ---------------------------------------------------------------------------------------------
// JKU poses.json.

// [R | t] with R a rotation about z by 30 degrees, written to 9 digits (|R^T R - I| ~ 1e-9, well
// inside the 1e-5 tolerance).
const char* kRow0[] = {"0.866025404", "-0.5", "0", "4.15129662"};
const char* kRow1[] = {"0.5", "0.866025404", "0", "-14.9073343"};
const char* kRow2[] = {"0", "0", "1", "55.9572182"};

std::string JkuMatrix(bool as_strings, const std::string& replace_01 = "") {
  std::string text = "[";
  const char** rows[3] = {kRow0, kRow1, kRow2};
  for (int r = 0; r < 3; ++r) {
    text += r ? ", [" : "[";
    for (int c = 0; c < 4; ++c) {
      std::string value = rows[r][c];
      if (r == 0 && c == 1 && !replace_01.empty()) value = replace_01;
      text += (c ? ", " : "") + (as_strings ? "\"" + value + "\"" : value);
    }
    text += "]";
  }
  return text + "]";
}

std::string JkuEntry(const std::string& imagefile, const std::string& matrix) {
  return "{\"imagefile\": \"" + imagefile + "\", \"M3x4\": " + matrix + "}";
}

std::string JkuFile(const std::vector<std::string>& entries) {
  std::string text = "{\"images\": [";
  for (size_t i = 0; i < entries.size(); ++i) text += (i ? ",\n" : "\n") + entries[i];
  return text + "]}";
}

class JkuTest : public FormatsTest {
 protected:
  // poses/poses.json and images/{a,b,c}.png, 8x6 grey frames.
  void SetUp() override {
    FormatsTest::SetUp();
    fs::create_directories(dir_ / "images");
    for (int i = 0; i < 3; ++i) {
      WriteImage(Path(std::string("images/") + "abc"[i] + ".png"),
                 MakePattern(8, 6, 1, PixelType::kU8, i));
    }
  }
  std::string Poses() const { return Path("poses/poses.json"); }
  void WritePoses(const std::vector<std::string>& entries) const {
    WriteText("poses/poses.json", JkuFile(entries));
  }
  void WriteValidPoses() const {
    WritePoses({JkuEntry("a.tiff", JkuMatrix(true)), JkuEntry("b.tiff", JkuMatrix(false)),
                JkuEntry("c.png", JkuMatrix(true))});
  }
};

TEST_F(JkuTest, LoadsStringAndNumberEntriesAndSubstitutesExtensions) {
  WriteValidPoses();
  const LoadResult loaded = LoadLightField(Poses(), Jku(50.0));
  EXPECT_EQ(loaded.format, "jku");
  const LightField& light_field = loaded.light_field;
  EXPECT_EQ(light_field.origin, Vec3d(0.0));
  ASSERT_EQ(light_field.views.size(), 3u);
  const Rigid3d expected = Rigid3d::FromMatrix3x4({0.866025404, -0.5, 0, 4.15129662, 0.5,
                                                   0.866025404, 0, -14.9073343, 0, 0, 1,
                                                   55.9572182});
  const PinholeCamera camera = PinholeCamera::FromFov(8, 6, 50.0);
  const char* names[] = {"a.tiff", "b.tiff", "c.png"};
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE(names[i]);
    const View& view = light_field.views[i];
    EXPECT_EQ(view.name, names[i]);
    EXPECT_EQ(fs::path(view.image_path).filename(), std::string(1, "abc"[i]) + ".png");
    ExpectSameCamera(view.camera, camera);
    // Strings and numbers parse to the same doubles.
    ExpectPoseNear(view.cam_from_world, expected, 0.0);
    ExpectSamePixels(view.image, MakePattern(8, 6, 1, PixelType::kU8, i));
  }
  // One note for both substituted frames, with the first as the example.
  ASSERT_EQ(loaded.notes.size(), 1u);
  EXPECT_THAT(loaded.notes[0], HasSubstr("poses.json: 2 frames named *.tiff were found as *.png"));
  EXPECT_THAT(loaded.notes[0], HasSubstr("a.tiff -> a.png"));
}

TEST_F(JkuTest, FramesFoundIgnoringCaseAndPosesOnlyNeedsOneFrame) {
  // a.PNG named as a.png (exact miss, case match); b.JPG named as b.jpg -> b.png.
  fs::rename(dir_ / "images" / "a.png", dir_ / "images" / "a.PNG");
  WritePoses({JkuEntry("a.png", JkuMatrix(true)), JkuEntry("b.JPG", JkuMatrix(false)),
              JkuEntry("c.png", JkuMatrix(true))});
  const LoadResult loaded = LoadLightField(Poses(), Jku(50.0));
  ASSERT_EQ(loaded.light_field.views.size(), 3u);
  EXPECT_EQ(fs::path(loaded.light_field.views[0].image_path).filename(), "a.PNG");
  EXPECT_EQ(fs::path(loaded.light_field.views[1].image_path).filename(), "b.png");
  ExpectSamePixels(loaded.light_field.views[0].image, MakePattern(8, 6, 1, PixelType::kU8, 0));
  ASSERT_EQ(loaded.notes.size(), 2u);
  EXPECT_THAT(loaded.notes[0], HasSubstr("a.png -> a.PNG"));
  EXPECT_THAT(loaded.notes[1], HasSubstr("b.JPG -> b.png"));

  // Poses only: missing frames are no error; the first one found sizes the camera.
  WritePoses({JkuEntry("gone.png", JkuMatrix(true)), JkuEntry("c.png", JkuMatrix(false))});
  LoadOptions poses_only = Jku(50.0);
  poses_only.load_images = false;
  const LoadResult partial = LoadLightField(Poses(), poses_only);
  ASSERT_EQ(partial.light_field.views.size(), 2u);
  EXPECT_EQ(partial.light_field.views[0].camera.width, 8);
  EXPECT_TRUE(partial.light_field.views[0].image.empty());
  EXPECT_THAT(partial.notes.back(), HasSubstr("1 of 2 frames not found"));
  // ... but decoding demands every frame.
  ExpectInvalid([&] { LoadLightField(Poses(), Jku(50.0)); },
                {"poses.json: image 0 (gone.png): imagefile: frame not found"});
  // No frame at all: the camera has no size.
  WritePoses({JkuEntry("gone.png", JkuMatrix(true))});
  ExpectInvalid([&] { LoadLightField(Poses(), poses_only); },
                {"poses.json", "none of the 1 frames was found", "image size"});
}

TEST_F(JkuTest, FramesFolderOptionAndFallbackToPosesFolder) {
  // images_dir overrides ../images.
  fs::create_directories(dir_ / "other");
  WriteImage(Path("other/a.png"), MakePattern(4, 4, 1, PixelType::kU8, 7));
  WritePoses({JkuEntry("a.png", JkuMatrix(false))});
  LoadOptions options = Jku();
  options.images_dir = Path("other");
  LoadResult loaded = LoadLightField(Poses(), options);
  ASSERT_EQ(loaded.light_field.views.size(), 1u);
  EXPECT_EQ(loaded.light_field.views[0].camera.width, 4);
  EXPECT_TRUE(loaded.notes.empty());
  // Without ../images, frames are looked up beside the poses file.
  fs::remove_all(dir_ / "images");
  WriteImage(Path("poses/a.png"), MakePattern(5, 3, 1, PixelType::kU8, 8));
  loaded = LoadLightField(Poses(), Jku());
  EXPECT_EQ(loaded.light_field.views[0].camera.width, 5);
  options.images_dir = Path("nowhere");
  ExpectInvalid([&] { LoadLightField(Poses(), options); }, {"poses.json", "images_dir", "nowhere"});
}

TEST_F(JkuTest, ReportsProgressAndHonoursCancel) {
  WriteValidPoses();
  struct Sink : ProgressSink {
    std::string stage;
    int64_t total = -1;
    std::atomic<int64_t> done{0};
    bool cancel = false;
    void Start(const std::string& s, int64_t t) override { stage = s, total = t; }
    void Advance(int64_t units) override { done += units; }
    bool Cancelled() override { return cancel; }
  };
  Sink sink;
  LoadLightField(Poses(), Jku(), &sink);
  EXPECT_EQ(sink.stage, "load");
  EXPECT_EQ(sink.total, 3);
  EXPECT_EQ(sink.done.load(), 3);
  sink.cancel = true;
  EXPECT_THROW(LoadLightField(Poses(), Jku(), &sink), Cancelled);
}

TEST_F(JkuTest, MissingFovIsAnError) {
  WriteValidPoses();
  ExpectInvalid([&] { LoadLightField(Poses()); }, {"poses.json", "fov_deg"});
}

TEST_F(JkuTest, MissingFrameNamesEntry) {
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true)), JkuEntry("zz.tiff", JkuMatrix(true)),
              JkuEntry("yy.tiff", JkuMatrix(true))});
  // Two frames are missing; the first one is reported whatever the thread scheduling.
  for (int threads : {1, 2, -1}) {
    LoadOptions options = Jku();
    options.num_threads = threads;
    ExpectInvalid([&] { LoadLightField(Poses(), options); },
                  {"poses.json", "image 1 (zz.tiff)", "imagefile", "not found"});
  }
}

TEST_F(JkuTest, FrameOfAnotherSizeIsAnError) {
  WriteImage(Path("images/c.png"), MakePattern(8, 5, 1, PixelType::kU8, 2));
  WriteValidPoses();
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 2 (c.png)", "8x5", "8x6"});
  // Poses only: only the first frame is opened (to size the camera); c.png is not.
  LoadOptions poses_only = Jku();
  poses_only.load_images = false;
  EXPECT_EQ(LoadLightField(Poses(), poses_only).light_field.views[2].camera.height, 6);
}

TEST_F(JkuTest, NanInPoseIsAnError) {
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true, "nan"))});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 0 (a.tiff)", "M3x4[0][1]", "not finite"});
}

TEST_F(JkuTest, NonOrthonormalRotationIsAnError) {
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true)), JkuEntry("b.tiff", JkuMatrix(false, "-0.6"))});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json: image 1 (b.tiff): M3x4: rotation is not orthonormal"});
}

TEST_F(JkuTest, NumericStringWithGarbageIsAnError) {
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true, "-0.5abc"))});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 0 (a.tiff)", "M3x4[0][1]", "\"-0.5abc\" is not a number"});
}

TEST_F(JkuTest, WrongMatrixShapeIsAnError) {
  WritePoses({JkuEntry("a.tiff", "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1]]")});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 0 (a.tiff)", "M3x4", "3 rows of 4"});
  WritePoses({JkuEntry("a.tiff", "[[1, 0, 0, 0], [0, 1, 0, 0]]")});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 0 (a.tiff)", "M3x4", "3 rows of 4"});
}

TEST_F(JkuTest, MissingFieldIsAnError) {
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true)), "{\"M3x4\": " + JkuMatrix(true) + "}"});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 1", "imagefile: missing"});
  WritePoses({JkuEntry("a.tiff", JkuMatrix(true)), "{\"imagefile\": \"b.tiff\"}"});
  ExpectInvalid([&] { LoadLightField(Poses(), Jku()); },
                {"poses.json", "image 1 (b.tiff)", "M3x4: missing"});
}

TEST(ParseNumberText, AcceptsDecimalNumbers) {
  EXPECT_EQ(ParseNumberText("0.559273303", "w"), 0.559273303);
  EXPECT_EQ(ParseNumberText("-14.9073343", "w"), -14.9073343);
  EXPECT_EQ(ParseNumberText("+2.5E+2", "w"), 250.0);
  EXPECT_EQ(ParseNumberText("1e-3", "w"), 1e-3);
  EXPECT_EQ(ParseNumberText(".5", "w"), 0.5);
  EXPECT_EQ(ParseNumberText("5.", "w"), 5.0);
  EXPECT_EQ(ParseNumberText("5432100.123456", "w"), 5432100.123456);
}

TEST(ParseNumberText, RejectsOtherText) {
  for (const char* text : {"", "0.5x", " 1", "1 ", "1e", "e5", ".", "-", "0x10", "1,5", "1..2",
                           "abc"}) {
    SCOPED_TRACE(text);
    ExpectInvalid([&] { ParseNumberText(text, "f.json: image 3"); },
                  {"f.json: image 3: \"" + std::string(text) + "\" is not a number"});
  }
  for (const char* text : {"nan", "NaN", "inf", "-Infinity", "1e999"}) {
    SCOPED_TRACE(text);
    ExpectInvalid([&] { ParseNumberText(text, "where"); }, {"where", text, "is not a number"});
  }
  ExpectInvalid([&] { ParseNumberText("nan", "where"); }, {"not finite"});
}

TEST(LoadOptions, Check) {
  LoadOptions options;
  EXPECT_NO_THROW(options.Check());
  options.fov_deg = 180.0;
  ExpectInvalid([&] { options.Check(); }, {"fov_deg"});
  options.fov_deg = std::numeric_limits<double>::quiet_NaN();
  ExpectInvalid([&] { options.Check(); }, {"fov_deg"});
  options.fov_deg = 40.0;
  options.num_threads = 0;
  ExpectInvalid([&] { options.Check(); }, {"num_threads"});
}

// ---------------------------------------------------------------------------------------------
// aos format errors.

// An aos file with one view "<image>" using camera "<camera_ref>" (camera cam0 is 8x6).
std::string AosFile(const std::string& image, const std::string& camera_ref = "cam0",
                    const std::string& rotation = "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                    const std::string& camera_extra = "\"fx\": 9, \"fy\": 9, \"cx\": 4, \"cy\": 3",
                    int version = 1) {
  return "{\"format\": \"aos-lightfield\", \"version\": " + std::to_string(version) +
         ", \"origin\": [1, 2, 3],"
         " \"cameras\": {\"cam0\": {\"model\": \"pinhole\", \"width\": 8, \"height\": 6, " +
         camera_extra +
         "}},"
         " \"views\": [{\"image\": \"" +
         image + "\", \"camera\": \"" + camera_ref + "\", \"cam_from_world\": {\"rotation\": " +
         rotation + ", \"translation\": [0, 0, 5]}}]}";
}

class AosErrorsTest : public FormatsTest {
 protected:
  void SetUp() override {
    FormatsTest::SetUp();
    fs::create_directories(dir_ / "views");
    WriteImage(Path("views/good.png"), MakePattern(8, 6, 1, PixelType::kU8, 0));
  }
  // Expects the error when the frames are decoded, and a load of poses and cameras only (which
  // opens no frame) to succeed.
  void ExpectFrameError(std::initializer_list<std::string> parts) {
    ExpectInvalid([&] { LoadLightField(Path("lf.json")); }, parts);
    const LoadResult poses_only = LoadLightField(Path("lf.json"), HeadersOnly());
    for (const View& view : poses_only.light_field.views) EXPECT_TRUE(view.image.empty());
  }
  // Expects the error in both loading modes.
  void ExpectLoadError(std::initializer_list<std::string> parts) {
    for (bool load_images : {true, false}) {
      SCOPED_TRACE(load_images ? "decoding" : "headers only");
      LoadOptions options;
      options.load_images = load_images;
      ExpectInvalid([&] { LoadLightField(Path("lf.json"), options); }, parts);
    }
  }
};

TEST_F(AosErrorsTest, ValidFileLoads) {
  WriteText("lf.json", AosFile("views/good.png"));
  const LoadResult loaded = LoadLightField(Path("lf.json"));
  ASSERT_EQ(loaded.light_field.views.size(), 1u);
  EXPECT_EQ(loaded.light_field.origin, Vec3d(1, 2, 3));
  EXPECT_EQ(loaded.light_field.views[0].camera.fx, 9.0);
  // fov_deg instead of fx/fy/cx/cy.
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                               "\"fov_deg\": 60"));
  ExpectSameCamera(LoadLightField(Path("lf.json")).light_field.views[0].camera,
                   PinholeCamera::FromFov(8, 6, 60.0));
  // An absolute image path.
  WriteText("lf.json", AosFile(Path("views/good.png")));
  EXPECT_EQ(LoadLightField(Path("lf.json")).light_field.views[0].image.width(), 8);
}

TEST_F(AosErrorsTest, MissingImageFile) {
  WriteText("lf.json", AosFile("views/missing.png"));
  ExpectFrameError({"lf.json", "view 0 (views/missing.png)", "not found"});
}

TEST_F(AosErrorsTest, UnreadableImage) {
  WriteText("views/garbage.png", "this is not a PNG file at all");
  WriteText("lf.json", AosFile("views/garbage.png"));
  ExpectFrameError({"lf.json", "view 0 (views/garbage.png)", "cannot read image"});
}

TEST_F(AosErrorsTest, FirstFailingFrameIsReportedWhateverTheScheduling) {
  // Views 0 and 1 decode, views 2 to 9 are garbage: the error names view 2 for any thread count.
  WriteText("views/garbage.png", "this is not a PNG file at all");
  std::string text = AosFile("views/good.png");
  const std::string view = text.substr(text.find("{\"image\""));
  const std::string one_view = view.substr(0, view.size() - 2);
  std::string more;
  for (int i = 1; i < 10; ++i) {
    std::string copy = one_view;
    if (i >= 2) copy.replace(copy.find("good.png"), 8, "garbage.png");
    more += ", " + copy;
  }
  text.insert(text.size() - 2, more);
  WriteText("lf.json", text);
  for (int threads : {1, 2, 4}) {
    LoadOptions options;
    options.num_threads = threads;
    ExpectInvalid([&] { LoadLightField(Path("lf.json"), options); },
                  {"lf.json: view 2 (views/garbage.png)", "cannot read image"});
  }
}

TEST_F(AosErrorsTest, ImageSizeDisagreesWithCamera) {
  WriteImage(Path("views/small.png"), MakePattern(7, 6, 1, PixelType::kU8, 0));
  WriteText("lf.json", AosFile("views/small.png"));
  ExpectFrameError({"lf.json", "view 0 (views/small.png)", "7x6", "camera says 8x6"});
}

TEST_F(AosErrorsTest, NanInPose) {
  // Bare NaN is not JSON: the parser refuses it, naming the file.
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[NaN, 0, 0], [0, 1, 0], [0, 0, 1]]"));
  ExpectLoadError({"lf.json", "not valid JSON"});
  // A string where a number belongs.
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[\"nan\", 0, 0], [0, 1, 0], [0, 0, 1]]"));
  ExpectLoadError({"lf.json", "/views/0/cam_from_world/rotation/0/0", "expected a number"});
}

TEST_F(AosErrorsTest, NonOrthonormalRotation) {
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0.2, 0], [0, 1, 0], [0, 0, 1]]"));
  ExpectLoadError(
      {"lf.json: /views/0/cam_from_world (view 0: views/good.png): rotation is not orthonormal"});
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0]]"));
  ExpectLoadError({"lf.json", "/views/0/cam_from_world/rotation", "3 rows of 3"});
}

TEST_F(AosErrorsTest, UnknownCameraId) {
  WriteText("lf.json", AosFile("views/good.png", "camX"));
  ExpectLoadError({"lf.json", "view 0 (views/good.png)", "camera", "unknown camera id \"camX\"",
                   "\"cam0\""});
}

TEST_F(AosErrorsTest, BadCameras) {
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                               "\"fx\": 9, \"fy\": 9, \"cx\": 4"));
  ExpectLoadError({"lf.json", "/cameras/cam0/cy: missing"});
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                               "\"fx\": -9, \"fy\": 9, \"cx\": 4, \"cy\": 3"));
  ExpectLoadError({"lf.json", "/cameras/cam0", "fx"});
  std::string text = AosFile("views/good.png");
  text.replace(text.find("\"pinhole\""), 9, "\"kannala\"");
  WriteText("lf.json", text);
  ExpectLoadError({"lf.json", "/cameras/cam0/model", "unknown lens model 'kannala'"});
  // A lens model's fov_deg must be one its radial map reaches, and its parameters valid.
  text = AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]", "\"fov_deg\": 200");
  text.replace(text.find("\"pinhole\""), 9, "\"radtan\"");
  WriteText("lf.json", text);
  ExpectLoadError({"lf.json", "/cameras/cam0", "fov_deg"});
  text = AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                 "\"fx\": 9, \"fy\": 9, \"cx\": 4, \"cy\": 3, \"xi\": -1");
  text.replace(text.find("\"pinhole\""), 9, "\"omnidir\"");
  WriteText("lf.json", text);
  ExpectLoadError({"lf.json", "/cameras/cam0", "xi: must be >= 0"});
}

// Every object of the file refuses keys it does not define, naming the key by its JSON pointer
// (the shared codec, json_codec.h): the camera, the pose, the origin's file level, the views and
// the pose record ("pose_source").
TEST_F(AosErrorsTest, MisspelledKeysAreRefusedWithTheirKeyPath) {
  const auto edited = [](const std::string& from, const std::string& to) {
    std::string text = AosFile("views/good.png");
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return text.replace(at, from.size(), to);
  };
  const struct {
    std::string text;
    std::string error;
  } cases[] = {
      {edited("\"origin\"", "\"orgin\""), "lf.json: /orgin: unknown key"},
      {edited("\"fx\"", "\"fxx\""), "lf.json: /cameras/cam0/fxx: unknown key"},
      {edited("\"image\"", "\"exposure\": 1, \"image\""), "lf.json: /views/0/exposure: unknown key"},
      {edited("\"translation\"", "\"scale\": 1, \"translation\""),
       "lf.json: /views/0/cam_from_world/scale (view 0: views/good.png): unknown key"},
      {edited("\"origin\"", "\"pose_source\": {\"method\": \"colmap\", \"pose_eror\": 1}, \"origin\""),
       "lf.json: /pose_source/pose_eror: unknown key"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.error);
    WriteText("lf.json", c.text);
    ExpectLoadError({c.error});
  }
  // The pose record as the writer writes it reads back.
  WriteText("lf.json", AosFile("views/good.png"));
  LightField light_field = LoadLightField(Path("lf.json")).light_field;
  light_field.pose_source =
      PoseSource{"colmap", 0.4, 20.0, 0.01, true, 0.2, "the frame of gps.csv", {"x.png"}};
  light_field.crs = "EPSG:32633";
  WriteLightField(Path("copy.json"), light_field);
  const LightField back = LoadLightField(Path("copy.json")).light_field;
  ASSERT_TRUE(back.pose_source.has_value());
  EXPECT_EQ(back.pose_source->world_frame, "the frame of gps.csv");
  EXPECT_EQ(back.pose_source->unregistered, std::vector<std::string>{"x.png"});
  EXPECT_EQ(back.crs, "EPSG:32633");
}

TEST_F(AosErrorsTest, CrsIsAnEpsgCodeCheckedWithProj) {
  const std::string good = AosFile("views/good.png");
  const auto with = [&](const std::string& insert) {
    std::string text = good;
    text.replace(text.find("\"origin\""), 8, insert + ", \"origin\"");
    return text;
  };
  WriteText("lf.json", with("\"crs\": \"EPSG:32633\""));
  EXPECT_EQ(LoadLightField(Path("lf.json")).light_field.crs, "EPSG:32633");
  const struct {
    std::string text, error;
  } cases[] = {
      {with("\"crs\": \"EPSG:999999\""), "lf.json: crs: EPSG:999999 is not known to PROJ"},
      {with("\"crs\": \"EPSG:4326\""), "lf.json: crs: EPSG:4326 (WGS 84) is geographic"},
      {with("\"crs\": \"UTM 33N\""), "lf.json: crs: \"UTM 33N\" is not an EPSG code"},
      {with("\"crs\": 32633"), "lf.json: crs: expected a string"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.error);
    WriteText("lf.json", c.text);
    ExpectLoadError({c.error});
  }
  // The writer refuses what the reader would.
  WriteText("lf.json", good);
  LightField light_field = LoadLightField(Path("lf.json")).light_field;
  light_field.crs = "EPSG:4326";
  ExpectInvalid([&] { WriteLightField(Path("out.json"), light_field); },
                {"out.json: crs: EPSG:4326 (WGS 84) is geographic"});
  EXPECT_FALSE(std::filesystem::exists(Path("out.json")));
  // Files from before "crs": a UTM label in pose_source.world_frame becomes the crs (with a
  // note); a free description stays a description.
  WriteText("old.json", with("\"pose_source\": {\"method\": \"colmap\", \"georeferenced\": true, "
                             "\"world_frame\": \"UTM 33N (WGS84)\"}"));
  const LoadResult old = LoadLightField(Path("old.json"));
  EXPECT_EQ(old.light_field.crs, "EPSG:32633");
  EXPECT_EQ(old.light_field.pose_source->world_frame, "");
  EXPECT_THAT(old.notes, testing::Contains(HasSubstr("read as crs EPSG:32633")));
  WriteText("old.json", with("\"pose_source\": {\"method\": \"colmap\", "
                             "\"world_frame\": \"UTM 19S (WGS84)\"}"));
  EXPECT_EQ(LoadLightField(Path("old.json")).light_field.crs, "EPSG:32719");
  WriteText("old.json", with("\"pose_source\": {\"method\": \"colmap\", "
                             "\"world_frame\": \"the frame of gps.csv\"}"));
  const LoadResult free = LoadLightField(Path("old.json"));
  EXPECT_EQ(free.light_field.crs, "");
  EXPECT_EQ(free.light_field.pose_source->world_frame, "the frame of gps.csv");
}

TEST_F(AosErrorsTest, LensCamerasLoadAndRoundTrip) {
  std::string text = AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                             "\"fx\": 9, \"fy\": 9, \"cx\": 4, \"cy\": 3, "
                             "\"distortion\": [0.01, -0.002, 0, 0]");
  text.replace(text.find("\"pinhole\""), 9, "\"fisheye\"");
  WriteText("lf.json", text);
  const LightField loaded = LoadLightField(Path("lf.json")).light_field;
  ASSERT_EQ(loaded.views[0].camera.model, LensModel::kFisheye);
  EXPECT_EQ(loaded.views[0].camera.distortion[0], 0.01);
  EXPECT_EQ(loaded.views[0].camera.fx, 9.0);
  WriteLightField(Path("copy.json"), loaded);
  const LightField again = LoadLightField(Path("copy.json")).light_field;
  EXPECT_EQ(again.views[0].camera.model, LensModel::kFisheye);
  EXPECT_EQ(again.views[0].camera.distortion, loaded.views[0].camera.distortion);
}

TEST_F(AosErrorsTest, VersionAndOrigin) {
  WriteText("lf.json", AosFile("views/good.png", "cam0", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
                               "\"fx\": 9, \"fy\": 9, \"cx\": 4, \"cy\": 3", 2));
  ExpectLoadError({"lf.json", "version"});
  std::string text = AosFile("views/good.png");
  text.replace(text.find("[1, 2, 3]"), 9, "[1, 2]");
  WriteText("lf.json", text);
  ExpectLoadError({"lf.json", "origin", "3 numbers"});
}

TEST_F(AosErrorsTest, ChannelCountsDiffer) {
  WriteImage(Path("views/rgb.png"), MakePattern(8, 6, 3, PixelType::kU8, 0));
  std::string text = AosFile("views/good.png");
  const std::string view = text.substr(text.find("{\"image\""));
  text.insert(text.size() - 2, ", " + view.substr(0, view.size() - 2));
  text.replace(text.rfind("views/good.png"), 14, "views/rgb.png");
  WriteText("lf.json", text);
  ExpectFrameError({"lf.json", "view 1 (views/rgb.png)", "3 channels", "view 0 has 1"});
}

TEST_F(AosErrorsTest, PosesOnlyOpensNoFrame) {
  // The frame is absent: poses and cameras still load, the view keeps its path and no image.
  WriteText("lf.json", AosFile("elsewhere/absent.png"));
  const LoadResult loaded = LoadLightField(Path("lf.json"), HeadersOnly());
  ASSERT_EQ(loaded.light_field.views.size(), 1u);
  const View& view = loaded.light_field.views[0];
  EXPECT_TRUE(view.image.empty());
  EXPECT_EQ(view.name, "elsewhere/absent.png");
  EXPECT_EQ(view.camera.fx, 9.0);
  EXPECT_TRUE(loaded.notes.empty());
}

TEST_F(AosErrorsTest, FrameFoundUnderANameDifferingInCase) {
  WriteImage(Path("views/Shot.JPG.png"), MakePattern(8, 6, 1, PixelType::kU8, 3));
  WriteText("lf.json", AosFile("views/shot.jpg.png"));
  const LoadResult loaded = LoadLightField(Path("lf.json"));
  ASSERT_EQ(loaded.light_field.views.size(), 1u);
  EXPECT_EQ(fs::path(loaded.light_field.views[0].image_path).filename(), "Shot.JPG.png");
  EXPECT_EQ(loaded.light_field.views[0].name, "views/shot.jpg.png");
  ExpectSamePixels(loaded.light_field.views[0].image, MakePattern(8, 6, 1, PixelType::kU8, 3));
  ASSERT_EQ(loaded.notes.size(), 1u);
  EXPECT_THAT(loaded.notes[0], HasSubstr("differs only in case"));
  EXPECT_THAT(loaded.notes[0], HasSubstr("views/shot.jpg.png -> Shot.JPG.png"));
  // Two candidates: an error naming both, in both loading modes.
  WriteImage(Path("views/SHOT.jpg.png"), MakePattern(8, 6, 1, PixelType::kU8, 4));
  ExpectLoadError({"lf.json: view 0 (views/shot.jpg.png): image", "2 files match it ignoring case",
                   "SHOT.jpg.png", "Shot.JPG.png"});
  // The exact name wins over its case variants.
  WriteImage(Path("views/shot.jpg.png"), MakePattern(8, 6, 1, PixelType::kU8, 5));
  const LoadResult exact = LoadLightField(Path("lf.json"));
  EXPECT_TRUE(exact.notes.empty());
  ExpectSamePixels(exact.light_field.views[0].image, MakePattern(8, 6, 1, PixelType::kU8, 5));
}

TEST_F(AosErrorsTest, GreyLoadsLuminance) {
  const Image rgb = MakePattern(8, 6, 3, PixelType::kU8, 1);
  WriteImage(Path("views/rgb.png"), rgb);
  WriteText("lf.json", AosFile("views/rgb.png"));
  LoadOptions options;
  options.grey = true;
  const Image grey = LoadLightField(Path("lf.json"), options).light_field.views[0].image;
  ASSERT_EQ(grey.channels(), 1);
  ASSERT_EQ(grey.type(), PixelType::kU8);
  ASSERT_GE(grey.border(), 1);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) {
      const double expected = std::round(0.299 * rgb.Value(x, y, 0) + 0.587 * rgb.Value(x, y, 1) +
                                         0.114 * rgb.Value(x, y, 2));
      ASSERT_EQ(grey.Value(x, y), expected) << x << "," << y;
    }
  }
  // Grey frames and RGB frames load into one light field as grey.
  std::string text = AosFile("views/good.png");
  const std::string view = text.substr(text.find("{\"image\""));
  text.insert(text.size() - 2, ", " + view.substr(0, view.size() - 2));
  text.replace(text.rfind("views/good.png"), 14, "views/rgb.png");
  WriteText("lf.json", text);
  const LightField mixed = LoadLightField(Path("lf.json"), options).light_field;
  EXPECT_EQ(mixed.views[0].image.channels(), 1);
  EXPECT_EQ(mixed.views[1].image.channels(), 1);
}

TEST_F(FormatsTest, UnknownFormat) {
  for (const char* text : {"{\"format\": \"colmap\"}", "{\"frames\": []}", "[1, 2]",
                           "{\"images\": [{\"imagefile\": \"a.png\"}]}"}) {
    SCOPED_TRACE(text);
    WriteText("lf.json", text);
    ExpectInvalid([&] { LoadLightField(Path("lf.json"), Jku()); },
                  {"lf.json", "unknown light-field format"});
  }
  ExpectInvalid([&] { LoadLightField(Path("absent.json")); }, {"absent.json"});
}

// ---------------------------------------------------------------------------------------------
// The real JKU F0 light field, when the shared data is present.

TEST(JkuF0, LoadsFirst30Frames) {
  const std::string poses = AOS_SHARED_DATA_DIR "/jku-f0/poses/poses_first30.json";
  if (!fs::exists(poses)) GTEST_SKIP() << poses << " is absent";
  const LoadResult loaded = LoadLightField(poses, Jku(50.815436217896945));
  EXPECT_EQ(loaded.format, "jku");
  const LightField& light_field = loaded.light_field;
  ASSERT_EQ(light_field.views.size(), 30u);
  for (const View& view : light_field.views) {
    EXPECT_EQ(view.image.width(), 512);
    EXPECT_EQ(view.image.height(), 512);
    EXPECT_EQ(view.image.channels(), 1);
    EXPECT_EQ(view.image.type(), PixelType::kU8);
    EXPECT_NEAR(view.camera.Pinhole().FovXDeg(), 50.815436217896945, 1e-9);
  }
  EXPECT_EQ(light_field.views[0].name, "20191004_091652.tiff");
  ASSERT_EQ(loaded.notes.size(), 1u);
  EXPECT_THAT(loaded.notes[0], HasSubstr("30 frames named *.tiff were found as *.png"));
  // The first pose, from the file (strings): centre C = -R^T t.
  const Vec3d centre = light_field.views[0].cam_from_world.Center();
  const Rigid3d first = Rigid3d::FromMatrix3x4({0.559273303, -0.826043189, 0.0697564408,
                                                4.15129662, 0.812924504, 0.530011594,
                                                -0.241332605, -14.9073343, 0.162379429,
                                                0.19167763, 0.967932045, 55.9572182});
  EXPECT_NEAR(glm::length(centre - first.Center()), 0.0, 1e-12);
}

}  // namespace
}  // namespace aos
