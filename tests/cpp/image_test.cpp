#include "aos/image/image.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
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

void ExpectInvalid(const std::function<void()>& call, std::initializer_list<std::string> parts) {
  try {
    call();
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    for (const std::string& part : parts) EXPECT_THAT(error.what(), HasSubstr(part));
  }
}

// A distinct value for every (x, y, c), exactly representable in every pixel type.
double PatternValue(int x, int y, int c) { return 1 + x + 10 * y + 100 * c; }

void SetValue(Image& image, int x, int y, int c, double value) {
  switch (image.type()) {
    case PixelType::kU8: image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(value); break;
    case PixelType::kU16: image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(value); break;
    case PixelType::kU32: image.At<uint32_t>(x, y)[c] = static_cast<uint32_t>(value); break;
    case PixelType::kF32: image.At<float>(x, y)[c] = static_cast<float>(value); break;
  }
}

// ---------------------------------------------------------------------------------------------
// Image

class ImageTypes : public testing::TestWithParam<PixelType> {};

TEST_P(ImageTypes, BorderReplicatesEdgesAndCorners) {
  const int width = 5, height = 4, channels = 2, border = 2;
  Image image(width, height, channels, GetParam(), border);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) SetValue(image, x, y, c, PatternValue(x, y, c));
    }
  }
  image.FillBorder();
  // Every pixel of the bordered area holds the nearest image pixel: edges take the edge row or
  // column, corners the corner pixel.
  for (int y = -border; y < height + border; ++y) {
    for (int x = -border; x < width + border; ++x) {
      const int nearest_x = std::clamp(x, 0, width - 1);
      const int nearest_y = std::clamp(y, 0, height - 1);
      for (int c = 0; c < channels; ++c) {
        ASSERT_EQ(image.Value(x, y, c), PatternValue(nearest_x, nearest_y, c))
            << "x=" << x << " y=" << y << " c=" << c;
      }
    }
  }
}

TEST_P(ImageTypes, CopyFromCopyToRoundTrip) {
  const int width = 3, height = 4, channels = 3;
  const PixelType type = GetParam();
  // Source rows padded to 11 values (9 used), destination rows to 13.
  Image source(width, height, channels, type, 0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) SetValue(source, x, y, c, PatternValue(x, y, c));
    }
  }
  const size_t value_size = PixelTypeSize(type);
  std::vector<unsigned char> padded(11 * height * value_size, 0xAB);
  for (int y = 0; y < height; ++y) {
    std::copy_n(static_cast<const unsigned char*>(source.RawAt(0, y)), 9 * value_size,
                padded.data() + y * 11 * value_size);
  }
  Image image(width, height, channels, type, 1);
  image.CopyFrom(padded.data(), 11);
  for (int y = -1; y <= height; ++y) {
    for (int x = -1; x <= width; ++x) {
      for (int c = 0; c < channels; ++c) {
        ASSERT_EQ(image.Value(x, y, c),
                  PatternValue(std::clamp(x, 0, width - 1), std::clamp(y, 0, height - 1), c));
      }
    }
  }
  std::vector<unsigned char> out(13 * height * value_size, 0xCD);
  image.CopyTo(out.data(), 13);
  for (int y = 0; y < height; ++y) {
    const unsigned char* row = out.data() + y * 13 * value_size;
    EXPECT_TRUE(std::equal(row, row + 9 * value_size, padded.data() + y * 11 * value_size));
    // Padding after the pixels is left alone.
    EXPECT_TRUE(std::all_of(row + 9 * value_size, row + 13 * value_size,
                            [](unsigned char b) { return b == 0xCD; }));
  }
}

INSTANTIATE_TEST_SUITE_P(AllTypes, ImageTypes,
                         testing::Values(PixelType::kU8, PixelType::kU16, PixelType::kU32,
                                         PixelType::kF32),
                         [](const testing::TestParamInfo<PixelType>& info) {
                           return std::string(PixelTypeName(info.param));
                         });

TEST(Image, LuminanceIsRec601InTheImagesType) {
  // Pure red, green, blue and white give the weights themselves (and their sum, 1).
  Image f(4, 1, 4, PixelType::kF32, 1);
  const float colours[4][4] = {{1, 0, 0, 0.5f}, {0, 1, 0, 0.5f}, {0, 0, 1, 0.5f}, {1, 1, 1, 0}};
  for (int x = 0; x < 4; ++x) {
    for (int c = 0; c < 4; ++c) f.At<float>(x, 0)[c] = colours[x][c];
  }
  f.FillBorder();
  const Image grey = LuminanceImage(f);
  ASSERT_EQ(grey.channels(), 1);
  ASSERT_EQ(grey.border(), 1);
  EXPECT_FLOAT_EQ(grey.At<float>(0, 0)[0], 0.299f);
  EXPECT_FLOAT_EQ(grey.At<float>(1, 0)[0], 0.587f);
  EXPECT_FLOAT_EQ(grey.At<float>(2, 0)[0], 0.114f);
  EXPECT_FLOAT_EQ(grey.At<float>(3, 0)[0], 1.0f);
  EXPECT_FLOAT_EQ(grey.At<float>(-1, -1)[0], 0.299f);  // the border too
  // 16-bit: rounded to nearest, white stays at the top of the range.
  Image u16(2, 1, 3, PixelType::kU16);
  for (int c = 0; c < 3; ++c) u16.At<uint16_t>(0, 0)[c] = 65535;
  u16.At<uint16_t>(1, 0)[0] = 1000;  // 299.0 exactly
  u16.At<uint16_t>(1, 0)[1] = 1;     // + 0.587
  const Image grey16 = LuminanceImage(u16);
  EXPECT_EQ(grey16.Value(0, 0), 65535.0);
  EXPECT_EQ(grey16.Value(1, 0), 300.0);
  // One or two channels: channel 0 as it is.
  Image two(1, 1, 2, PixelType::kU8);
  two.At<uint8_t>(0, 0)[0] = 17;
  two.At<uint8_t>(0, 0)[1] = 200;
  EXPECT_EQ(LuminanceImage(two).Value(0, 0), 17.0);
  EXPECT_TRUE(LuminanceImage(Image()).empty());
}

TEST(Image, PixelTypeRangesAreOneHelper) {
  // The templated maximum is the full range of the runtime type, bit for bit, and the integer
  // type's largest value; float images hold [0, 1].
  static_assert(PixelTypeMax<uint8_t>() == 255.0, "uint8");
  static_assert(PixelTypeMax<uint16_t>() == 65535.0, "uint16");
  static_assert(PixelTypeMax<uint32_t>() == 4294967295.0, "uint32");
  EXPECT_EQ(PixelTypeFullRange(PixelType::kU8), PixelTypeMax<uint8_t>());
  EXPECT_EQ(PixelTypeFullRange(PixelType::kU16), PixelTypeMax<uint16_t>());
  EXPECT_EQ(PixelTypeFullRange(PixelType::kU32), PixelTypeMax<uint32_t>());
  EXPECT_EQ(PixelTypeFullRange(PixelType::kF32), 1.0);
  EXPECT_EQ(1.0 / PixelTypeFullRange(PixelType::kU16), 1.0 / 65535.0);
}

TEST(Image, SizesAndErrors) {
  const Image image(6, 5, 3, PixelType::kU16, 1);
  EXPECT_EQ(image.row_stride(), 8 * 3);
  EXPECT_EQ(image.PixelBytes(), 6u * 5 * 3 * 2);
  EXPECT_EQ(image.AllocatedBytes(), 8u * 7 * 3 * 2);
  EXPECT_TRUE(Image().empty());
  ExpectInvalid([] { Image(0, 5, 1, PixelType::kU8); }, {"width and height"});
  ExpectInvalid([] { Image(4, 5, 5, PixelType::kU8); }, {"channels"});
  ExpectInvalid([] { Image(4, 5, 1, PixelType::kU8, -1); }, {"border"});
}

// ---------------------------------------------------------------------------------------------
// image_io and file_util, in a fresh folder per test.

class FilesTest : public testing_util::TempFolderTest {
 protected:
  std::vector<std::string> Entries() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      names.push_back(entry.path().filename().string());
    }
    return names;
  }
};

// An image whose values sweep the type's range (and negatives/fractions for float).
Image Sweep(int width, int height, int channels, PixelType type) {
  Image image(width, height, channels, type, 0);
  int k = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c, ++k) {
        double value = 0.0;
        switch (type) {
          case PixelType::kU8: value = (k * 37) % 256; break;
          case PixelType::kU16: value = (k * 4099) % 65536; break;
          case PixelType::kU32: value = k * 100003.0; break;
          case PixelType::kF32: value = static_cast<float>((k - 20) * 0.123456789e3); break;
        }
        SetValue(image, x, y, c, value);
      }
    }
  }
  // Make sure the extremes occur.
  if (type == PixelType::kU8) SetValue(image, 0, 0, 0, 255);
  if (type == PixelType::kU16) SetValue(image, 0, 0, 0, 65535);
  return image;
}

void ExpectSameValues(const Image& a, const Image& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  ASSERT_EQ(a.channels(), b.channels());
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      for (int c = 0; c < a.channels(); ++c) {
        ASSERT_EQ(a.Value(x, y, c), b.Value(x, y, c)) << "x=" << x << " y=" << y << " c=" << c;
      }
    }
  }
}

void ExpectRoundTrip(const std::string& path, const Image& image, PixelType read_type) {
  WriteImage(path, image);
  const ImageFileInfo info = ReadImageInfo(path);
  EXPECT_EQ(info.width, image.width());
  EXPECT_EQ(info.height, image.height());
  EXPECT_EQ(info.channels, image.channels());
  EXPECT_EQ(info.type, read_type);
  const Image read = ReadImage(path, 1);
  EXPECT_EQ(read.type(), read_type);
  EXPECT_EQ(read.border(), 1);
  ExpectSameValues(read, image);
  // The border is filled on reading.
  EXPECT_EQ(read.Value(-1, -1), image.Value(0, 0));
  EXPECT_EQ(read.Value(image.width(), image.height()),
            image.Value(image.width() - 1, image.height() - 1));
}

TEST_F(FilesTest, Png8BitRoundTrip) {
  ExpectRoundTrip(Path("a.png"), Sweep(17, 9, 3, PixelType::kU8), PixelType::kU8);
}

TEST_F(FilesTest, Png16BitRoundTrip) {
  ExpectRoundTrip(Path("a.png"), Sweep(17, 9, 1, PixelType::kU16), PixelType::kU16);
}

TEST_F(FilesTest, TiffFloatRoundTrip) {
  ExpectRoundTrip(Path("a.tif"), Sweep(17, 9, 1, PixelType::kF32), PixelType::kF32);
}

TEST_F(FilesTest, ExrFloatRoundTrip) {
  ExpectRoundTrip(Path("a.exr"), Sweep(17, 9, 3, PixelType::kF32), PixelType::kF32);
}

TEST_F(FilesTest, FloatToUint8UsesTheRangeAndClamps) {
  Image image(7, 1, 1, PixelType::kF32);
  const float values[7] = {5.0f, 10.0f, 15.0f, 20.0f, 25.0f, 12.0f,
                           std::numeric_limits<float>::quiet_NaN()};
  for (int x = 0; x < 7; ++x) image.At<float>(x, 0)[0] = values[x];
  WriteImageOptions options;
  options.range_min = 10.0;
  options.range_max = 20.0;
  WriteImage(Path("n.png"), image, options);
  const Image read = ReadImage(Path("n.png"));
  ASSERT_EQ(read.type(), PixelType::kU8);
  // code = round((v - 10) / 10 * 255), clamped to [0, 255]; NaN -> 0.
  const double expected[7] = {0, 0, 128 /* 127.5 rounds up */, 255, 255, 51, 0};
  for (int x = 0; x < 7; ++x) EXPECT_EQ(read.Value(x, 0), expected[x]) << "x=" << x;

  // The same to 16 bits: 65535 codes.
  options.sample_type = SampleType::kU16;
  WriteImage(Path("n16.png"), image, options);
  const Image read16 = ReadImage(Path("n16.png"));
  ASSERT_EQ(read16.type(), PixelType::kU16);
  EXPECT_EQ(read16.Value(2, 0), 32768.0);  // round(32767.5)
  EXPECT_EQ(read16.Value(5, 0), 13107.0);  // round(0.2 * 65535)
  EXPECT_EQ(read16.Value(4, 0), 65535.0);
}

TEST_F(FilesTest, CountImageTooLargeForPngFailsAndLeavesNoFile) {
  Image counts(3, 2, 1, PixelType::kU32);
  counts.At<uint32_t>(1, 1)[0] = 70000;
  ExpectInvalid([&] { WriteImage(Path("counts.png"), counts); },
                {"counts.png", "70000", "does not fit"});
  EXPECT_THAT(Entries(), testing::IsEmpty());
  // Counts that fit are stored unchanged as 16-bit; TIFF keeps 32 bits.
  counts.At<uint32_t>(1, 1)[0] = 65535;
  WriteImage(Path("counts.png"), counts);
  EXPECT_EQ(ReadImage(Path("counts.png")).Value(1, 1), 65535.0);
  counts.At<uint32_t>(1, 1)[0] = 70000;
  WriteImage(Path("counts.tif"), counts);
  EXPECT_EQ(ReadImage(Path("counts.tif")).Value(1, 1), 70000.0);
}

TEST_F(FilesTest, WriteIntoMissingFolderFailsNamingThePath) {
  const std::string path = Path("missing/a.png");
  ExpectInvalid([&] { WriteImage(path, Sweep(4, 4, 1, PixelType::kU8)); }, {path});
  EXPECT_FALSE(fs::exists(dir_ / "missing"));
}

TEST_F(FilesTest, WriteErrors) {
  const Image image = Sweep(4, 4, 1, PixelType::kU8);
  ExpectInvalid([&] { WriteImage(Path("a.exr"), image); }, {"a.exr", "EXR"});
  ExpectInvalid([&] { WriteImage(Path("a.png"), Image()); }, {"a.png", "empty"});
  WriteImageOptions options;
  options.range_min = options.range_max = 5.0;
  ExpectInvalid([&] { WriteImage(Path("a.png"), Sweep(4, 4, 1, PixelType::kF32), options); },
                {"range"});
  EXPECT_THAT(Entries(), testing::IsEmpty());
  ExpectInvalid([] { ParseSampleType("int8"); }, {"sample_type", "int8"});
  EXPECT_EQ(ParseSampleType("uint16"), SampleType::kU16);
}

TEST_F(FilesTest, ReadErrorsNameTheFile) {
  ExpectInvalid([&] { ReadImage(Path("absent.png")); }, {"absent.png", "not found"});
  std::ofstream(Path("garbage.png")) << "not an image";
  ExpectInvalid([&] { ReadImage(Path("garbage.png")); }, {"garbage.png", "cannot read image"});
  ExpectInvalid([&] { ReadImageInfo(Path("garbage.png")); }, {"garbage.png"});
}

TEST_F(FilesTest, TruncatedJpegIsRefusedNamingTheFile) {
  // A JPEG cut anywhere before its end-of-image marker is refused. libjpeg decodes this one (a
  // gradient) without its last two bytes, the marker, without a word (other cuts it reports as
  // "Premature end of JPEG file"). The whole file, and one with bytes after EOI, still read.
  Image image(64, 48, 1, PixelType::kU8);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) *image.At<uint8_t>(x, y) = static_cast<uint8_t>(x + y);
  }
  WriteImage(Path("whole.jpg"), image);
  std::ifstream in(Path("whole.jpg"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 500u);
  ASSERT_EQ(bytes.substr(bytes.size() - 2), "\xff\xd9");
  EXPECT_EQ(ReadImage(Path("whole.jpg")).width(), 64);
  std::ofstream(Path("trailer.jpg"), std::ios::binary) << bytes << std::string(100, '\0');
  EXPECT_EQ(ReadImage(Path("trailer.jpg")).width(), 64);
  for (const size_t keep : {bytes.size() - 2, bytes.size() / 2, size_t{400}}) {
    std::ofstream(Path("cut.jpg"), std::ios::binary) << bytes.substr(0, keep);
    ExpectInvalid([&] { ReadImage(Path("cut.jpg")); }, {"cut.jpg", "truncated JPEG"});
  }
}

// file_util

TEST_F(FilesTest, PendingFileWithoutCommitLeavesNothing) {
  std::string temp_path;
  {
    PendingFile pending(Path("out.txt"));
    temp_path = pending.TempPath();
    EXPECT_EQ(fs::path(temp_path).parent_path(), dir_);
    EXPECT_EQ(fs::path(temp_path).extension(), ".txt");
    std::ofstream(temp_path) << "partial";
    EXPECT_TRUE(fs::exists(temp_path));
  }
  EXPECT_THAT(Entries(), testing::IsEmpty());
  {
    PendingFile pending(Path("out.txt"));
    std::ofstream(pending.TempPath()) << "done";
    pending.Commit();
  }
  EXPECT_THAT(Entries(), testing::ElementsAre("out.txt"));
  EXPECT_EQ(ReadTextFile(Path("out.txt")), "done");
}

TEST_F(FilesTest, CheckOutputPath) {
  std::ofstream(Path("input.png")) << "x";
  ExpectInvalid([&] { CheckOutputPath(Path("input.png"), {Path("other.png"), Path("input.png")}); },
                {"input.png", "refusing to overwrite"});
  // The same file through a link is still the input.
  fs::create_symlink(Path("input.png"), Path("link.png"));
  ExpectInvalid([&] { CheckOutputPath(Path("link.png"), {Path("input.png")}); },
                {"refusing to overwrite"});
  ExpectInvalid([&] { CheckOutputPath(Path("missing/out.png"), {}); },
                {"missing", "does not exist"});
  EXPECT_NO_THROW(CheckOutputPath(Path("new.png"), {Path("input.png")}));
  // An existing file that is not an input may be replaced.
  EXPECT_NO_THROW(CheckOutputPath(Path("input.png"), {Path("other.png")}));
}

TEST_F(FilesTest, TextFiles) {
  WriteTextFileAtomic(Path("a.json"), "{\"a\": 1}\n");
  EXPECT_EQ(ReadTextFile(Path("a.json")), "{\"a\": 1}\n");
  EXPECT_THAT(Entries(), testing::ElementsAre("a.json"));
  ExpectInvalid([&] { ReadTextFile(Path("absent.json")); }, {"absent.json"});
  ExpectInvalid([&] { WriteTextFileAtomic(Path("missing/a.json"), "x"); }, {"missing/a.json"});
}

}  // namespace
}  // namespace aos

namespace aos {
namespace {

TEST_F(FilesTest, CommitTogetherIsAllOrNothing) {
  auto write = [](const std::string& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
  };
  auto read = [](const std::string& path) {
    std::ifstream stream(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(stream), {});
  };
  write(Path("a.txt"), "old a");
  {
    PendingFile a(Path("a.txt")), b(Path("b.txt"));
    write(a.TempPath(), "new a");
    // b's temporary file vanishes: its rename fails after a's would have succeeded.
    EXPECT_THROW(CommitTogether({&a, &b}), std::invalid_argument);
  }
  EXPECT_EQ(read(Path("a.txt")), "old a") << "a must be restored";
  EXPECT_EQ(Entries(), std::vector<std::string>{"a.txt"}) << "no new, temporary or backup file";
  {
    PendingFile a(Path("a.txt")), b(Path("b.txt"));
    write(a.TempPath(), "new a");
    write(b.TempPath(), "new b");
    CommitTogether({&a, &b});
  }
  EXPECT_EQ(read(Path("a.txt")), "new a");
  EXPECT_EQ(read(Path("b.txt")), "new b");
  auto entries = Entries();
  std::sort(entries.begin(), entries.end());
  EXPECT_EQ(entries, (std::vector<std::string>{"a.txt", "b.txt"}));
}

}  // namespace
}  // namespace aos
