#pragma once
// Reading and writing image files through OpenImageIO (PNG, TIFF, EXR, JPEG, ...).
//
// Reading keeps the file's native type where aos has one (8-bit, 16-bit, 32-bit float); other
// types (half, 32-bit int, double) are converted to 32-bit float. 1 to 4 channels.
//
// Writing: float images go to EXR/TIFF as 32-bit float unchanged; integer outputs (PNG/TIFF 8 or
// 16 bit) use the stated normalisation code = round((value - range_min) / (range_max - range_min)
// * max_code), clamped to [0, max_code]; integer images written to an integer type of at least
// their size are stored unchanged. Writes go to a temporary file renamed into place on success.
#include <cmath>
#include <optional>
#include <string>

#include "aos/image/image.h"

namespace aos {

struct ImageFileInfo {
  int width = 0;
  int height = 0;
  int channels = 0;
  PixelType type = PixelType::kU8;  // type the image will have once read
  std::string description;          // the file's ImageDescription, if any
};

// Header only. Throws std::invalid_argument "<path>: <reason>" if unreadable.
ImageFileInfo ReadImageInfo(const std::string& path);

// A frame's GPS position from its EXIF tags (GPS:Latitude/LatitudeRef, GPS:Longitude/
// LongitudeRef, GPS:Altitude/AltitudeRef), WGS84 degrees (south and west negative) and metres;
// nullopt when the frame has no latitude/longitude. altitude_m is NaN when absent. Throws like
// ReadImageInfo for an unreadable file, and for malformed tags (naming the tag): a hemisphere
// letter (GPS:LatitudeRef, GPS:LongitudeRef) missing or other than N/S and E/W, a non-finite
// angle or altitude.
struct GpsTag {
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  double altitude_m = std::nan("");
};
std::optional<GpsTag> ReadGpsTag(const std::string& path);

// A frame's capture time from EXIF DateTimeOriginal ("YYYY:MM:DD HH:MM:SS", the camera's clock,
// no time zone) and SubSecTimeOriginal (the digits of a fraction of a second) when present:
// seconds since 1970-01-01 00:00:00 of that clock, for ordering the frames of one flight.
// nullopt when the frame has no DateTimeOriginal, or EXIF's "unknown" (blanks, or zeros as
// "0000:00:00 00:00:00"). Throws like ReadImageInfo for an unreadable
// file, and for a malformed date or sub-second tag (naming the tag).
std::optional<double> ReadCaptureTime(const std::string& path);

// Reads the whole image with `border` replicated border pixels (see Image).
Image ReadImage(const std::string& path, int border = 0);

enum class SampleType { kAuto, kU8, kU16, kU32, kF32 };
// "auto", "uint8", "uint16", "uint32", "float32"; throws std::invalid_argument for other names.
SampleType ParseSampleType(const std::string& name);
const char* SampleTypeName(SampleType type);

// How float images become integer samples: one rule, used by the CLI and Python alike. A float
// image's values are in the units of a pixel type (`units`; aos renders keep the views' units:
// 0..255 for 8-bit views, 0..65535 for 16-bit, 0..1 for float). Written to an integer format with
// sample_type auto, the samples take that type's depth (uint16 for float units, so no precision
// is lost to 8 bits), and [range_min, range_max] defaults to the units' full range.
struct WriteImageOptions {
  // Sample type in the file. kAuto: float32 for .exr/.tif/.tiff/.pfm; for other formats, a float
  // image takes the depth of `units` (uint8 for 8-bit units, uint16 for 16-bit or float units),
  // and integer images (e.g. count maps) their own type where the format allows it.
  SampleType sample_type = SampleType::kAuto;
  // The pixel type whose units a float image's values are in (see above).
  PixelType units = PixelType::kU8;
  // Value mapped to code 0 when converting a float image to integer samples; NaN = 0.
  double range_min = std::nan("");
  // Value mapped to the largest code (255 or 65535); NaN = the full range of `units` (255, 65535,
  // or 1 for float). Must be > range_min.
  double range_max = std::nan("");
  // Free text stored in the file's ImageDescription (e.g. how it was normalised).
  std::string description;
  // zlib compression level of PNG files, 0 (none) .. 9 (smallest). 1 by default: for typical
  // 8-bit frames it writes several times faster than zlib's default 6 for files about 10-25%
  // larger (docs/benchmarks.md, tools/bench_write.py). Other formats ignore it.
  int png_compression_level = 1;
  void Check() const;
  // [range_min, range_max] with the defaults filled in.
  double RangeMin() const;
  double RangeMax() const;
};

// Writes `image` to `path` (format from the extension). Throws std::invalid_argument naming the
// file on failure; no partial file is left behind. Polls the process's output cancellation
// (SetCommitCancelled, file_util.h; the CLI sets it) between bands of rows and throws
// aos::Cancelled when it answers true.
void WriteImage(const std::string& path, const Image& image, const WriteImageOptions& options = {});

// The sample type WriteImage will use for `image` at `path` under `options`. Throws
// std::invalid_argument naming the file for an extension no image writer takes (or none) and for
// a sample type the format cannot hold (EXR integers, PNG float, JPEG 16-bit), so callers check
// an output this way before any work.
SampleType ResolveSampleType(const std::string& path, const Image& image,
                             const WriteImageOptions& options);

}  // namespace aos
