#include "aos/image/image_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <png.h>
#include <zlib.h>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/memory.h"

namespace aos {
namespace {

namespace oiio = OIIO;

PixelType NativeType(const oiio::TypeDesc& format) {
  if (format == oiio::TypeDesc::UINT8) return PixelType::kU8;
  if (format == oiio::TypeDesc::UINT16) return PixelType::kU16;
  return PixelType::kF32;
}

oiio::TypeDesc ToTypeDesc(PixelType type) {
  switch (type) {
    case PixelType::kU8: return oiio::TypeDesc::UINT8;
    case PixelType::kU16: return oiio::TypeDesc::UINT16;
    case PixelType::kU32: return oiio::TypeDesc::UINT32;
    case PixelType::kF32: return oiio::TypeDesc::FLOAT;
  }
  return oiio::TypeDesc::UNKNOWN;
}

std::string LowerExtension(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

// A PNG file's chunk structure and checksums, walked before libpng sees the file: libpng prints
// its own "libpng error: ..." line to stderr on a damaged file (OpenImageIO does not catch it),
// so damage is found here first and reported as one error naming the file. A file that starts
// with "\x89PNG" but not the whole signature is damaged (libpng: "corrupted by ASCII
// conversion"); any other file is left to the decoders.
void CheckPngChunks(const std::string& path, uint64_t file_bytes) {
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  std::ifstream file(path, std::ios::binary);
  unsigned char signature[8] = {};
  file.read(reinterpret_cast<char*>(signature), 8);
  if (std::memcmp(signature, kSignature, 4) != 0) return;
  if (file.gcount() < 8 || std::memcmp(signature, kSignature, 8) != 0) {
    ThrowInvalid(path + ": damaged PNG file: its 8-byte signature is " +
                 (file.gcount() < 8 ? std::string("cut short") : std::string("altered")) +
                 " (as by a text-mode transfer; nothing was decoded)");
  }
  uint64_t offset = 8;
  std::vector<unsigned char> data;
  while (true) {
    unsigned char header[8];
    const auto damaged = [&](const std::string& what) {
      ThrowInvalid(path + ": damaged PNG file: " + what + " (byte " + std::to_string(offset) +
                   " of " + std::to_string(file_bytes) + "; nothing was decoded)");
    };
    if (!file.read(reinterpret_cast<char*>(header), 8)) damaged("the file ends before IEND");
    const uint64_t length = (uint64_t{header[0]} << 24) | (uint64_t{header[1]} << 16) |
                            (uint64_t{header[2]} << 8) | header[3];
    std::string type(reinterpret_cast<const char*>(header + 4), 4);
    for (char& c : type) {
      if (!std::isalpha(static_cast<unsigned char>(c))) damaged("invalid chunk type");
    }
    if (length > 0x7FFFFFFFu || offset + 12 + length > file_bytes) {
      damaged("chunk " + type + " runs past the end of the file");
    }
    data.resize(static_cast<size_t>(length) + 4);
    std::memcpy(data.data(), header + 4, 4);
    unsigned char crc_bytes[4];
    if (!file.read(reinterpret_cast<char*>(data.data() + 4), static_cast<std::streamsize>(length)) ||
        !file.read(reinterpret_cast<char*>(crc_bytes), 4)) {
      damaged("chunk " + type + " runs past the end of the file");
    }
    const uint32_t stored = (uint32_t{crc_bytes[0]} << 24) | (uint32_t{crc_bytes[1]} << 16) |
                            (uint32_t{crc_bytes[2]} << 8) | crc_bytes[3];
    const uint32_t computed = static_cast<uint32_t>(
        ::crc32(::crc32(0L, Z_NULL, 0), data.data(), static_cast<uInt>(data.size())));
    if (stored != computed) damaged("chunk " + type + " fails its CRC check");
    offset += 12 + length;
    if (type == "IEND") return;
  }
}

// A JPEG file's markers, walked before libjpeg sees the file: libjpeg only warns ("Premature end
// of JPEG file") when the data stops early and fills the missing rows with grey, which
// OpenImageIO passes on as pixels. The walk follows the segments (each with its length) to the
// first scan, then the entropy-coded data (where 0xFF is followed by 0x00 stuffing, a restart
// marker or fill bytes) and any further segments and scans, to the end-of-image marker; a file
// that ends first is truncated. A file that does not start with SOI (FF D8 FF) is left to the
// decoders; bytes after EOI (a second image, padding) are not read.
void CheckJpegEnd(const std::string& path, uint64_t file_bytes) {
  std::ifstream file(path, std::ios::binary);
  unsigned char start[3] = {};
  if (!file.read(reinterpret_cast<char*>(start), 3) || start[0] != 0xFF || start[1] != 0xD8 ||
      start[2] != 0xFF) {
    return;
  }
  file.seekg(2);
  std::vector<char> buffer(size_t{1} << 16);
  size_t size = 0, next = 0;
  uint64_t offset = 2;  // of the next byte
  const auto byte = [&]() -> int {
    if (next == size) {
      file.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      size = static_cast<size_t>(file.gcount());
      next = 0;
      if (size == 0) {
        ThrowInvalid(path + ": truncated JPEG file: it ends at byte " + std::to_string(file_bytes) +
                     " before its end-of-image marker (nothing was decoded)");
      }
    }
    ++offset;
    return static_cast<unsigned char>(buffer[next++]);
  };
  const auto skip_segment = [&] {
    const int high = byte();
    const int length = (high << 8) | byte();
    if (length < 2) {
      ThrowInvalid(path + ": damaged JPEG file: a segment of length " + std::to_string(length) +
                   " at byte " + std::to_string(offset - 2) + " (nothing was decoded)");
    }
    for (int i = 2; i < length; ++i) byte();
  };
  while (true) {
    // Entropy-coded data, or extraneous bytes between segments (libjpeg skips them too).
    int c = byte();
    if (c != 0xFF) continue;
    do c = byte(); while (c == 0xFF);  // fill bytes
    // Stuffing, RSTn, TEM and SOI carry no length.
    if (c == 0x00 || (c >= 0xD0 && c <= 0xD8) || c == 0x01) continue;
    if (c == 0xD9) return;  // EOI
    skip_segment();  // for SOS its header; the entropy-coded data follows
  }
}

// PNG through libpng directly, with its errors and warnings captured: OpenImageIO 2.4 leaves
// libpng's default handlers in place, which print "libpng error: ..." to stderr before OpenImageIO
// reports the failure (two error lines for one damaged file). Headers are validated here before
// OpenImageIO opens a PNG, and pixels are decoded here (same layout as OpenImageIO's: palettes
// expanded to RGB, grey below 8 bits to 8 bits, tRNS to an alpha channel, 16-bit samples in host
// order).
class PngReader {
 public:
  PngReader(const std::string& path) : path_(path) {
    file_ = std::fopen(path.c_str(), "rb");
    if (file_ == nullptr) ThrowInvalid(path + ": cannot open image file");
    png_ = png_create_read_struct(PNG_LIBPNG_VER_STRING, this, &PngReader::OnError,
                                  &PngReader::OnWarning);
    if (png_ != nullptr) info_ = png_create_info_struct(png_);
    if (png_ == nullptr || info_ == nullptr) {
      Close();
      ThrowInvalid(path + ": cannot read image (libpng could not start)");
    }
  }
  ~PngReader() { Close(); }
  PngReader(const PngReader&) = delete;
  PngReader& operator=(const PngReader&) = delete;

  // Reads and checks the header (IHDR and the chunks before the pixels); sets the transforms.
  // Returns false with error() set if libpng refused it.
  bool ReadHeader() {
    if (setjmp(png_jmpbuf(png_))) return false;
    png_init_io(png_, file_);
    png_read_info(png_, info_);
    const int color_type = png_get_color_type(png_, info_);
    const int bit_depth = png_get_bit_depth(png_, info_);
    if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png_);
    if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png_);
    if (png_get_valid(png_, info_, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png_);
    if (bit_depth == 16) png_set_swap(png_);  // network to host (little-endian) order
    png_set_interlace_handling(png_);
    png_read_update_info(png_, info_);
    return true;
  }
  int channels() const { return png_get_channels(png_, info_); }
  int bit_depth() const { return png_get_bit_depth(png_, info_); }

  // Decodes every row into `rows` (one pointer per row). Returns false with error() set if
  // libpng failed (a damaged zlib stream, missing data).
  bool ReadRows(png_bytep* rows) {
    if (setjmp(png_jmpbuf(png_))) return false;
    png_read_image(png_, rows);
    png_read_end(png_, nullptr);
    return true;
  }
  const std::string& error() const { return error_; }

 private:
  static void OnError(png_structp png, png_const_charp message) {
    static_cast<PngReader*>(png_get_error_ptr(png))->error_ = message;
    png_longjmp(png, 1);
  }
  static void OnWarning(png_structp, png_const_charp) {}  // ancillary problems: not fatal
  void Close() {
    if (png_ != nullptr) png_destroy_read_struct(&png_, info_ != nullptr ? &info_ : nullptr, nullptr);
    if (file_ != nullptr) std::fclose(file_);
    png_ = nullptr;
    info_ = nullptr;
    file_ = nullptr;
  }

  std::string path_;
  std::FILE* file_ = nullptr;
  png_structp png_ = nullptr;
  png_infop info_ = nullptr;
  std::string error_;
};

bool IsPngFile(const std::string& path) {
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  std::ifstream file(path, std::ios::binary);
  unsigned char signature[8] = {};
  return file.read(reinterpret_cast<char*>(signature), 8) &&
         std::memcmp(signature, kSignature, 8) == 0;
}

void CheckPngHeader(const std::string& path) {
  PngReader reader(path);
  if (!reader.ReadHeader()) {
    ThrowInvalid(path + ": cannot read image (PNG: " + OneLine(reader.error()) + ")");
  }
}

// Decodes a PNG whose header OpenImageIO reported as `image`'s size, channels and type.
void DecodePng(const std::string& path, Image* image) {
  PngReader reader(path);
  if (!reader.ReadHeader()) {
    ThrowInvalid(path + ": cannot read image (PNG: " + OneLine(reader.error()) + ")");
  }
  const int depth = image->type() == PixelType::kU16 ? 16 : 8;
  if (reader.channels() != image->channels() || reader.bit_depth() != depth ||
      (image->type() != PixelType::kU8 && image->type() != PixelType::kU16)) {
    ThrowInvalid(path + ": unsupported PNG layout (" + std::to_string(reader.channels()) +
                 " channels of " + std::to_string(reader.bit_depth()) + " bits)");
  }
  std::vector<png_bytep> rows(static_cast<size_t>(image->height()));
  for (int y = 0; y < image->height(); ++y) {
    rows[static_cast<size_t>(y)] = static_cast<png_bytep>(image->RawAt(0, y));
  }
  if (!reader.ReadRows(rows.data())) {
    ThrowInvalid(path + ": cannot decode image (PNG: " + OneLine(reader.error()) + ")");
  }
}

// Samples as stored: a 2- or 4-channel PNG or TIFF is read without multiplying the other channels
// by the last one (OpenImageIO "associates" alpha by default), so what aos writes reads back
// bit for bit.
const oiio::ImageSpec& RawSamplesConfig() {
  static const oiio::ImageSpec config = [] {
    oiio::ImageSpec spec;
    spec.attribute("oiio:UnassociatedAlpha", 1);
    return spec;
  }();
  return config;
}

// An OpenEXR file's header attributes, walked before OpenEXR sees the file: OpenEXR allocates
// an attribute's declared size before reading it, so a 24-byte file declaring a 2 GiB string
// attribute would cost 2 GiB. Every attribute (name\0 type\0 int32 size, then size bytes) must
// lie inside the file. A file that does not start with the EXR magic is left to the decoders.
void CheckExrHeader(const std::string& path, uint64_t file_bytes) {
  static const unsigned char kMagic[4] = {0x76, 0x2f, 0x31, 0x01};
  std::ifstream file(path, std::ios::binary);
  unsigned char start[8] = {};
  if (!file.read(reinterpret_cast<char*>(start), 8) || std::memcmp(start, kMagic, 4) != 0) return;
  const bool multipart = (start[5] & 0x10) != 0;  // version flags, bit 12
  uint64_t offset = 8;
  const auto damaged = [&](const std::string& what) {
    ThrowInvalid(path + ": damaged OpenEXR file: " + what + " (byte " + std::to_string(offset) +
                 " of " + std::to_string(file_bytes) + "; nothing was decoded)");
  };
  const auto read_name = [&](std::string* name) {
    name->clear();
    char c = 0;
    while (true) {
      if (!file.get(c)) damaged("the header ends before its attributes do");
      ++offset;
      if (c == '\0') return;
      if (name->size() >= 255) damaged("an attribute name or type longer than 255 bytes");
      name->push_back(c);
    }
  };
  std::string name;
  std::string type;
  for (int part = 0;; ++part) {
    int attributes = 0;
    while (true) {
      read_name(&name);
      if (name.empty()) break;  // the end of this part's header
      read_name(&type);
      unsigned char size_bytes[4];
      if (!file.read(reinterpret_cast<char*>(size_bytes), 4)) damaged("attribute " + name + " is cut");
      offset += 4;
      const int32_t size = static_cast<int32_t>(
          uint32_t{size_bytes[0]} | (uint32_t{size_bytes[1]} << 8) |
          (uint32_t{size_bytes[2]} << 16) | (uint32_t{size_bytes[3]} << 24));
      if (size < 0 || offset + static_cast<uint64_t>(size) > file_bytes) {
        damaged("attribute " + name + " declares " + std::to_string(size) +
                " bytes, past the end of the file");
      }
      file.seekg(size, std::ios::cur);
      offset += static_cast<uint64_t>(size);
      ++attributes;
    }
    // A single-part header ends at its first empty name; a multi-part file's list of headers
    // ends with an empty header.
    if (!multipart || attributes == 0) return;
  }
}

std::unique_ptr<oiio::ImageInput> Open(const std::string& path) {
  // Regular files only: a FIFO blocks the decoder forever and /dev/zero never ends.
  const uint64_t file_bytes = CheckRegularFile(path, "image file");
  CheckPngChunks(path, file_bytes);
  if (IsPngFile(path)) CheckPngHeader(path);
  CheckExrHeader(path, file_bytes);
  auto input = oiio::ImageInput::open(path, &RawSamplesConfig());
  if (!input) {
    std::string reason = oiio::geterror();
    if (reason.empty()) reason = "unknown reason";
    ThrowInvalid(path + ": cannot read image (" + reason + ")");
  }
  return input;
}

// Refuses a header whose pixels cannot be in a file of this size, before anything is decoded:
// lossless codecs the formats use (deflate, LZW, PackBits, RLE, PIZ) shrink even a constant image
// by far less than kMaxCompressionRatio, so a 69-byte PNG claiming 46340 x 46340 pixels is a lie,
// not an image. Also refuses images larger than the memory budget.
void CheckPlausibleSize(const std::string& path, const oiio::ImageSpec& spec, PixelType type,
                        bool check_budget = true) {
  constexpr uint64_t kMaxCompressionRatio = 16384;
  constexpr uint64_t kAlwaysPlausibleBytes = uint64_t{64} << 20;
  const uint64_t file_bytes = CheckRegularFile(path, "image file");
  // Integer types aos reads as float (int8/16/32/64, uint32/64) pass through a buffer of the
  // file's own type first: both are in memory at once.
  const bool converted = !spec.format.is_floating_point() && type == PixelType::kF32;
  const uint64_t sample_bytes = PixelTypeSize(type) + (converted ? spec.format.size() : 0);
  const uint64_t decoded = SaturatingProduct(
      {static_cast<uint64_t>(spec.width), static_cast<uint64_t>(spec.height),
       static_cast<uint64_t>(spec.nchannels), sample_bytes});
  const std::string size = std::to_string(spec.width) + "x" + std::to_string(spec.height) + "x" +
                           std::to_string(spec.nchannels);
  if (decoded > kAlwaysPlausibleBytes && decoded / kMaxCompressionRatio > file_bytes) {
    ThrowInvalid(path + ": the header claims " + size + " pixels (" + FormatBytes(decoded) +
                 " decoded) but the file has only " + std::to_string(file_bytes) +
                 " bytes; a damaged or forged header (nothing was decoded)");
  }
  if (check_budget) {
    CheckMemoryBudget(decoded, path + ": image of " + size + " pixels", "decoded samples");
  }
}

// Reads every pixel of `input` as `type` into `data` (rows y_stride bytes apart). A compressed
// TIFF is read one scanline at a time: OpenImageIO 2.4 inflates whole deflate strips itself in
// read_image and ignores a stream that fails (the strip comes back as zeros, no error), while
// its scanline path goes through libtiff, which reports it.
bool ReadAllPixels(oiio::ImageInput& input, const oiio::TypeDesc& type, void* data,
                   oiio::stride_t x_stride, oiio::stride_t y_stride) {
  const oiio::ImageSpec& spec = input.spec();
  const bool compressed_tiff = input.format_name() == std::string("tiff") &&
                               spec.tile_width == 0 &&
                               spec.get_int_attribute("tiff:Compression", 1) != 1;
  if (!compressed_tiff) {
    return input.read_image(0, 0, 0, spec.nchannels, type, data, x_stride, y_stride);
  }
  auto* row = static_cast<unsigned char*>(data);
  for (int y = 0; y < spec.height; ++y, row += y_stride) {
    if (!input.read_scanline(spec.y + y, 0, type, row, x_stride)) return false;
  }
  return true;
}

// OpenImageIO's error text for `input` (the reader's, else the global one), or a fallback.
std::string ReaderError(oiio::ImageInput& input) {
  std::string reason = input.geterror();
  if (reason.empty()) reason = oiio::geterror();
  return reason.empty() ? std::string("unknown reason") : reason;
}

}  // namespace

ImageFileInfo ReadImageInfo(const std::string& path) {
  auto input = Open(path);
  const oiio::ImageSpec& spec = input->spec();
  CheckPlausibleSize(path, spec, NativeType(spec.format), /*check_budget=*/false);
  ImageFileInfo info;
  info.width = spec.width;
  info.height = spec.height;
  info.channels = spec.nchannels;
  info.type = NativeType(spec.format);
  info.description = spec.get_string_attribute("ImageDescription");
  input->close();
  return info;
}

std::optional<GpsTag> ReadGpsTag(const std::string& path) {
  auto input = Open(path);
  const oiio::ImageSpec& spec = input->spec();
  // Degrees, minutes, seconds (three rationals or floats) and a hemisphere letter: `positive`
  // or `negative` (either case), nothing else; a missing letter leaves the hemisphere unknown.
  const auto angle = [&](const char* name, const char* ref_name, char positive, char negative,
                         double* degrees) {
    const oiio::ParamValue* value = spec.find_attribute(name);
    if (value == nullptr) return false;
    const int n = static_cast<int>(value->type().numelements() * value->type().aggregate);
    if (n != 3 && n != 1) ThrowInvalid(path + ": " + name + ": expected degrees, minutes, seconds");
    double dms[3] = {0, 0, 0};
    for (int i = 0; i < n; ++i) dms[i] = value->get_float_indexed(i);
    *degrees = dms[0] + dms[1] / 60.0 + dms[2] / 3600.0;
    if (!std::isfinite(*degrees)) ThrowInvalid(path + ": " + name + ": not finite");
    // Unsigned (the letter gives the sign), minutes and seconds below 60, the angle within its
    // range: "91 minutes" or "3600 seconds" is a corrupt tag, not a position.
    const double max_degrees = positive == 'N' ? 90.0 : 180.0;
    if (dms[0] < 0 || dms[1] < 0 || dms[2] < 0 || (n == 3 && (dms[1] >= 60 || dms[2] >= 60)) ||
        *degrees > max_degrees) {
      ThrowInvalid(path + ": " + name + ": " + FormatNumber(dms[0]) + " deg " +
                   FormatNumber(dms[1]) + "' " + FormatNumber(dms[2]) +
                   "\" is not an angle of 0 to " + FormatNumber(max_degrees) +
                   " degrees (minutes and seconds below 60)");
    }
    std::string ref = spec.get_string_attribute(ref_name);
    while (!ref.empty() && (ref.back() == ' ' || ref.back() == '\0')) ref.pop_back();
    const char letter = ref.size() == 1 ? static_cast<char>(std::toupper(ref[0])) : '\0';
    if (letter != positive && letter != negative) {
      ThrowInvalid(path + ": " + ref_name + ": " +
                   (ref.empty() ? std::string("missing") : "\"" + ref + "\" is not") + " " +
                   positive + " or " + negative + " (the hemisphere of " + name + ")");
    }
    if (letter == negative) *degrees = -*degrees;
    return true;
  };
  GpsTag tag;
  const bool has_latitude =
      angle("GPS:Latitude", "GPS:LatitudeRef", 'N', 'S', &tag.latitude_deg);
  const bool has_longitude =
      angle("GPS:Longitude", "GPS:LongitudeRef", 'E', 'W', &tag.longitude_deg);
  if (!has_latitude || !has_longitude) return std::nullopt;
  if (const oiio::ParamValue* altitude = spec.find_attribute("GPS:Altitude")) {
    tag.altitude_m = altitude->get_float_indexed(0);
    if (!std::isfinite(tag.altitude_m)) ThrowInvalid(path + ": GPS:Altitude: not finite");
    if (spec.get_int_attribute("GPS:AltitudeRef", 0) == 1) tag.altitude_m = -tag.altitude_m;
  }
  input->close();
  return tag;
}

std::optional<double> ReadCaptureTime(const std::string& path) {
  auto input = Open(path);
  const oiio::ImageSpec& spec = input->spec();
  const oiio::ParamValue* date = spec.find_attribute("Exif:DateTimeOriginal");
  if (date == nullptr) return std::nullopt;
  const std::string text = spec.get_string_attribute("Exif:DateTimeOriginal");
  const std::string subsec = spec.get_string_attribute("Exif:SubsecTimeOriginal");
  input->close();
  // EXIF's "unknown": blanks or zeros ("0000:00:00 00:00:00", a camera whose clock was never set).
  if (text.find_first_not_of(" :0-\0") == std::string::npos) return std::nullopt;
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0, used = 0;
  char s1 = 0, s2 = 0;
  const bool parsed = std::sscanf(text.c_str(), "%4d%c%2d%c%2d %2d:%2d:%2d%n", &year, &s1, &month,
                                  &s2, &day, &hour, &minute, &second, &used) == 8;
  if (!parsed || (s1 != ':' && s1 != '-') || s2 != s1 || month < 1 || month > 12 || day < 1 ||
      day > 31 || hour > 23 || minute > 59 || second > 60 || hour < 0 || minute < 0 ||
      second < 0) {
    ThrowInvalid(path + ": Exif:DateTimeOriginal: \"" + text +
                 "\" is not a date and time YYYY:MM:DD HH:MM:SS");
  }
  // Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
  const int y = year - (month <= 2 ? 1 : 0);
  const int era = (y >= 0 ? y : y - 399) / 400;
  const int yoe = y - era * 400;
  const int doy = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  const double days = static_cast<double>(era) * 146097.0 + doe - 719468.0;
  double seconds = days * 86400.0 + hour * 3600.0 + minute * 60.0 + second;
  std::string digits = subsec;
  while (!digits.empty() && (digits.back() == ' ' || digits.back() == '\0')) digits.pop_back();
  if (!digits.empty()) {
    if (digits.size() > 9 ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      ThrowInvalid(path + ": Exif:SubsecTimeOriginal: \"" + digits +
                   "\" is not the digits of a fraction of a second");
    }
    seconds += std::stod("0." + digits);
  }
  return seconds;
}

Image ReadImage(const std::string& path, int border) {
  // Pixels only (header readers skip it: the whole file is walked), before the decoder sees it.
  CheckJpegEnd(path, CheckRegularFile(path, "image file"));
  auto input = Open(path);
  const oiio::ImageSpec& spec = input->spec();
  if (spec.nchannels < 1 || spec.nchannels > 4) {
    ThrowInvalid(path + ": image has " + std::to_string(spec.nchannels) +
                 " channels; aos reads 1 to 4");
  }
  if (spec.width <= 0 || spec.height <= 0) ThrowInvalid(path + ": image is empty");
  // A header can claim any size; refuse absurd ones instead of failing in the allocator.
  constexpr int64_t kMaxPixels = int64_t{1} << 31;
  if (static_cast<int64_t>(spec.width) * spec.height > kMaxPixels) {
    ThrowInvalid(path + ": image of " + std::to_string(spec.width) + "x" +
                 std::to_string(spec.height) + " pixels is larger than aos accepts (2^31 pixels)");
  }
  CheckPlausibleSize(path, spec, NativeType(spec.format));
  Image image;
  try {
    image = Image(spec.width, spec.height, spec.nchannels, NativeType(spec.format), border);
  } catch (const std::bad_alloc&) {
    ThrowInvalid(path + ": not enough memory to decode this " + std::to_string(spec.width) + "x" +
                 std::to_string(spec.height) + " image");
  }
  const oiio::stride_t value_size = static_cast<oiio::stride_t>(PixelTypeSize(image.type()));
  const oiio::stride_t x_stride = value_size * image.channels();
  const oiio::stride_t y_stride = value_size * image.row_stride();
  auto fail = [&] { ThrowInvalid(path + ": cannot decode image (" + ReaderError(*input) + ")"); };
  const oiio::TypeDesc file_type = spec.format;
  const bool other_integer = !file_type.is_floating_point() && image.type() == PixelType::kF32;
  // libtiff reports a damaged compressed strip (a deflate stream that fails) through its error
  // handler, which OpenImageIO 2.4 passes to the global (per-thread) error, while read_image
  // returns true with zeros in place of the strip: clear it now, check it after.
  oiio::geterror(true);
  if (other_integer) {
    // OpenImageIO converts integers to float normalised to [0, 1] (or [-1, 1]); aos keeps their
    // values (a uint32 count map of 70000 reads as 70000.0), so read natively and convert here.
    const size_t count = static_cast<size_t>(spec.width) * spec.height * spec.nchannels;
    std::vector<unsigned char> buffer(count * file_type.size());
    const oiio::stride_t file_x_stride = static_cast<oiio::stride_t>(file_type.size()) * spec.nchannels;
    if (!ReadAllPixels(*input, file_type, buffer.data(), file_x_stride,
                       file_x_stride * spec.width)) {
      fail();
    }
    auto convert = [&](auto tag) {
      using Value = decltype(tag);
      const Value* values = reinterpret_cast<const Value*>(buffer.data());
      size_t i = 0;
      for (int y = 0; y < spec.height; ++y) {
        float* row = image.At<float>(0, y);
        for (int x = 0; x < spec.width * spec.nchannels; ++x) {
          row[x] = static_cast<float>(values[i++]);
        }
      }
    };
    switch (file_type.basetype) {
      case oiio::TypeDesc::INT8: convert(int8_t{}); break;
      case oiio::TypeDesc::INT16: convert(int16_t{}); break;
      case oiio::TypeDesc::UINT32: convert(uint32_t{}); break;
      case oiio::TypeDesc::INT32: convert(int32_t{}); break;
      case oiio::TypeDesc::UINT64: convert(uint64_t{}); break;
      case oiio::TypeDesc::INT64: convert(int64_t{}); break;
      default:
        ThrowInvalid(path + ": unsupported sample type " + std::string(file_type.c_str()));
    }
  } else if (input->format_name() == std::string("png")) {
    DecodePng(path, &image);
  } else if (!ReadAllPixels(*input, ToTypeDesc(image.type()), image.RawAt(0, 0), x_stride,
                            y_stride)) {
    fail();
  }
  // Some readers (TIFF strips past the end of the file, for one) report missing data only in
  // their error state while read_image returns true: a truncated file is an error, never pixels
  // padded with junk.
  if (input->has_error()) fail();
  if (oiio::has_error()) {
    ThrowInvalid(path + ": cannot decode image (" + OneLine(oiio::geterror(true)) + ")");
  }
  input->close();
  if (auto problem = DescribeNonFinite(image)) {
    ThrowInvalid(path + ": " + *problem + "; aos refuses non-finite samples in its inputs");
  }
  image.FillBorder();
  return image;
}

SampleType ParseSampleType(const std::string& name) {
  if (name == "auto") return SampleType::kAuto;
  if (name == "uint8" || name == "8") return SampleType::kU8;
  if (name == "uint16" || name == "16") return SampleType::kU16;
  if (name == "uint32") return SampleType::kU32;
  if (name == "float32" || name == "float" || name == "32f") return SampleType::kF32;
  ThrowInvalid("sample_type: expected auto, uint8, uint16, uint32 or float32 (got '" + name + "')");
}

const char* SampleTypeName(SampleType type) {
  switch (type) {
    case SampleType::kAuto: return "auto";
    case SampleType::kU8: return "uint8";
    case SampleType::kU16: return "uint16";
    case SampleType::kU32: return "uint32";
    case SampleType::kF32: return "float32";
  }
  return "?";
}

double WriteImageOptions::RangeMin() const { return std::isnan(range_min) ? 0.0 : range_min; }

double WriteImageOptions::RangeMax() const {
  return std::isnan(range_max) ? PixelTypeFullRange(units) : range_max;
}

void WriteImageOptions::Check() const {
  if (units == PixelType::kU32) {
    ThrowInvalid("units: must be uint8, uint16 or float32 (the views' sample types)");
  }
  if (png_compression_level < 0 || png_compression_level > 9) {
    ThrowInvalid("png_compression_level: must be 0..9 (got " +
                 std::to_string(png_compression_level) + ")");
  }
  if (!std::isfinite(RangeMin()) || !std::isfinite(RangeMax()) || !(RangeMax() > RangeMin())) {
    ThrowInvalid("range: range_max must be greater than range_min and both finite (got [" +
                 FormatNumber(RangeMin()) + ", " + FormatNumber(RangeMax()) + "])");
  }
}

SampleType ResolveSampleType(const std::string& path, const Image& image,
                             const WriteImageOptions& options) {
  const std::string extension = LowerExtension(path);
  // The format first, so a render is never made for a file no writer takes.
  if (extension.empty() || !oiio::ImageOutput::create(path)) {
    oiio::geterror(true);  // OpenImageIO's own text ("could not find a format writer ...")
    ThrowInvalid(path + ": " +
                 (extension.empty() ? std::string("no file extension")
                                    : "no image format has the extension " + extension) +
                 " (the extension picks the format: .png, .tif, .exr, .jpg, ...)");
  }
  const bool float_format = extension == ".exr" || extension == ".tif" || extension == ".tiff" ||
                            extension == ".pfm" || extension == ".hdr";
  const bool tiff = extension == ".tif" || extension == ".tiff";
  SampleType type = options.sample_type;
  if (type == SampleType::kAuto) {
    switch (image.type()) {
      case PixelType::kF32:
        type = float_format ? SampleType::kF32
                            : (options.units == PixelType::kU8 ? SampleType::kU8 : SampleType::kU16);
        break;
      case PixelType::kU8: type = SampleType::kU8; break;
      case PixelType::kU16: type = SampleType::kU16; break;
      case PixelType::kU32:
        type = tiff ? SampleType::kU32 : (float_format ? SampleType::kF32 : SampleType::kU16);
        break;
    }
  }
  if (extension == ".exr" && type != SampleType::kF32) {
    ThrowInvalid(path + ": EXR files hold float samples; use .png or .tif for " +
                 SampleTypeName(type));
  }
  if (extension == ".png" && type != SampleType::kU8 && type != SampleType::kU16) {
    ThrowInvalid(path + ": PNG files hold 8- or 16-bit samples, not " +
                 std::string(SampleTypeName(type)) + "; use .tif or .exr");
  }
  if ((extension == ".jpg" || extension == ".jpeg") && type != SampleType::kU8) {
    ThrowInvalid(path + ": JPEG files hold 8-bit samples only");
  }
  return type;
}

void WriteImage(const std::string& path, const Image& image, const WriteImageOptions& options) {
  if (image.empty()) ThrowInvalid(path + ": nothing to write (empty image)");
  options.Check();
  const SampleType sample_type = ResolveSampleType(path, image, options);
  const int width = image.width(), height = image.height(), channels = image.channels();
  const size_t count = static_cast<size_t>(width) * height * channels;

  // Convert into a contiguous buffer of the file's sample type.
  std::vector<unsigned char> buffer;
  oiio::TypeDesc file_type;
  const bool integer_image = image.type() != PixelType::kF32;
  auto for_each_value = [&](auto&& store) {
    size_t i = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        for (int c = 0; c < channels; ++c) store(i++, image.Value(x, y, c));
      }
    }
  };
  auto to_codes = [&](auto code_type_tag) {
    using Code = decltype(code_type_tag);
    constexpr double max_code = PixelTypeMax<Code>();
    buffer.resize(count * sizeof(Code));
    Code* out = reinterpret_cast<Code*>(buffer.data());
    // Integer images already in a type that fits keep their values unchanged.
    const bool keep = integer_image && image.type() != PixelType::kU32 &&
                      PixelTypeSize(image.type()) <= sizeof(Code);
    const bool keep_counts = image.type() == PixelType::kU32;
    if (keep && PixelTypeSize(image.type()) == sizeof(Code)) {
      image.CopyTo(out, static_cast<ptrdiff_t>(width) * channels);  // same type: rows as they are
      return;
    }
    const double range_min = options.RangeMin();
    const double scale = max_code / (options.RangeMax() - range_min);
    for_each_value([&](size_t i, double value) {
      double code;
      if (keep) {
        code = value;
      } else if (keep_counts) {
        if (value > max_code) {
          ThrowInvalid(path + ": value " + FormatNumber(value) + " does not fit in " +
                       SampleTypeName(sample_type) + "; write a .tif (uint32) or .exr instead");
        }
        code = value;
      } else {
        code = std::isfinite(value) ? std::round((value - range_min) * scale) : 0.0;
        code = std::clamp(code, 0.0, max_code);
      }
      out[i] = static_cast<Code>(code);
    });
  };
  switch (sample_type) {
    case SampleType::kU8: to_codes(uint8_t{}); file_type = oiio::TypeDesc::UINT8; break;
    case SampleType::kU16: to_codes(uint16_t{}); file_type = oiio::TypeDesc::UINT16; break;
    case SampleType::kU32: {
      if (image.type() != PixelType::kU32) {
        ThrowInvalid(path + ": uint32 output is for count maps (uint32 images) only");
      }
      to_codes(uint32_t{});
      file_type = oiio::TypeDesc::UINT32;
      break;
    }
    case SampleType::kF32:
    case SampleType::kAuto: {
      buffer.resize(count * sizeof(float));
      float* out = reinterpret_cast<float*>(buffer.data());
      for_each_value([&](size_t i, double value) { out[i] = static_cast<float>(value); });
      file_type = oiio::TypeDesc::FLOAT;
      break;
    }
  }

  PendingFile pending(path);
  auto output = oiio::ImageOutput::create(pending.TempPath());
  if (!output) {
    ThrowInvalid(path + ": no image writer for this file extension (" + oiio::geterror() + ")");
  }
  oiio::ImageSpec spec(width, height, channels, file_type);
  if (!options.description.empty()) spec.attribute("ImageDescription", options.description);
  if (LowerExtension(path) == ".exr") spec.attribute("compression", "zip");
  // PNG: the samples as given (OpenImageIO would divide the others by the last channel). Not
  // for TIFF, where the attribute tags the last channel as alpha and makes other programs
  // multiply by it on reading.
  if (LowerExtension(path) == ".png") {
    spec.attribute("oiio:UnassociatedAlpha", 1);
    spec.attribute("png:compressionLevel", options.png_compression_level);
  }
  auto fail = [&] {
    std::string reason = output->geterror();
    ThrowInvalid(path + ": cannot write image (" + (reason.empty() ? "unknown reason" : reason) +
                 ")");
  };
  ThrowIfOutputCancelled();  // before open: a PNG closed with no rows makes libpng print
  if (!output->open(pending.TempPath(), spec)) fail();
  // In bands of rows, the process's cancellation polled between them (a 2048^2 float TIFF takes
  // about a second): a signal stops the write, and the temporary file goes with `pending`.
  const size_t row_bytes = static_cast<size_t>(width) * channels * file_type.size();
  constexpr int kBandRows = 64;
  for (int y = 0; y < height; y += kBandRows) {
    ThrowIfOutputCancelled();
    const int end = std::min(height, y + kBandRows);
    if (!output->write_scanlines(y, end, 0, file_type, buffer.data() + row_bytes * y)) fail();
  }
  if (!output->close()) fail();
  output.reset();
  ThrowIfOutputCancelled();
  // libtiff reports some failures (a full disk, a file-size limit) only as a file that cannot
  // be read back, while every call above succeeds: read the file back, and compare it where the
  // format is lossless, before it replaces anything.
  {
    bool intact_png = true;  // checked first: libpng would print its own error line
    try {
      CheckPngChunks(pending.TempPath(), CheckRegularFile(pending.TempPath()));
    } catch (const std::invalid_argument&) {
      intact_png = false;
    }
    auto input =
        intact_png ? oiio::ImageInput::open(pending.TempPath(), &RawSamplesConfig()) : nullptr;
    std::vector<unsigned char> check(buffer.size());
    const bool readable =
        input && input->spec().width == width && input->spec().height == height &&
        input->spec().nchannels == channels &&
        input->read_image(0, 0, 0, channels, file_type, check.data());
    if (!readable || (LowerExtension(path) != ".jpg" && LowerExtension(path) != ".jpeg" &&
                      check != buffer)) {
      ThrowInvalid(path + ": cannot write image (the written file does not read back intact; "
                          "is the disk full?)");
    }
  }
  pending.Commit();
}

}  // namespace aos
