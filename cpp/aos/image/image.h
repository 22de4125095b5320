#pragma once
// Images in their native pixel type (8-bit, 16-bit, 32-bit unsigned, 32-bit float), interleaved
// channels, rows top to bottom. Views of a light field are kept this way rather than as float
// copies, so a light field costs what its decoded frames cost.
//
// Storage may carry a border of `border` pixels around the image (views use border 1, filled by
// replicating the edge pixels) so that bilinear sampling anywhere in the continuous image area
// [0, width] x [0, height] needs no bounds checks: its taps fall in [-1, width] x [-1, height].
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>

namespace aos {

enum class PixelType { kU8, kU16, kU32, kF32 };

// Bytes per channel value (inline: pixel addressing in the renderers' inner loops uses it).
inline size_t PixelTypeSize(PixelType type) {
  switch (type) {
    case PixelType::kU8: return 1;
    case PixelType::kU16: return 2;
    case PixelType::kU32: return 4;
    case PixelType::kF32: return 4;
  }
  return 0;
}
// "uint8", "uint16", "uint32", "float32" (also the numpy dtype name).
const char* PixelTypeName(PixelType type);
// The inverse of PixelTypeName; throws std::invalid_argument "<where>: ..." for other names.
PixelType ParsePixelTypeName(const std::string& name, const std::string& where);
// The full value range of a pixel type: 255 (uint8), 65535 (uint16), 4294967295 (uint32) and 1
// for float32 (whose images hold values in [0, 1] by convention).
double PixelTypeFullRange(PixelType type);
// The same range for a sample type known at compile time: PixelTypeMax<uint8_t>() = 255.0,
// <uint16_t> 65535.0, <uint32_t> 4294967295.0 (integer types only; float's range is 1).
template <typename T>
constexpr double PixelTypeMax() {
  static_assert(std::numeric_limits<T>::is_integer, "PixelTypeMax: an integer sample type");
  return static_cast<double>(std::numeric_limits<T>::max());
}

class Image {
 public:
  Image() = default;
  // A zero-filled image. Throws std::invalid_argument for non-positive sizes or channels
  // outside 1..4.
  Image(int width, int height, int channels, PixelType type, int border = 0);

  bool empty() const { return width_ == 0; }
  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  int border() const { return border_; }
  PixelType type() const { return type_; }
  // Elements (not bytes) from one row to the next, border included.
  ptrdiff_t row_stride() const { return row_stride_; }
  // Bytes of the pixels themselves (width * height * channels * value size), border excluded.
  size_t PixelBytes() const;
  // Bytes held, border included.
  size_t AllocatedBytes() const { return bytes_; }

  // Pointer to channel 0 of pixel (x, y); -border <= x < width + border, likewise y.
  template <typename T>
  T* At(int x, int y) {
    return reinterpret_cast<T*>(data_.get()) + Offset(x, y);
  }
  template <typename T>
  const T* At(int x, int y) const {
    return reinterpret_cast<const T*>(data_.get()) + Offset(x, y);
  }
  void* RawAt(int x, int y) { return data_.get() + Offset(x, y) * PixelTypeSize(type_); }
  const void* RawAt(int x, int y) const {
    return data_.get() + Offset(x, y) * PixelTypeSize(type_);
  }

  // Copies interleaved pixels (rows of width * channels values, `src_row_stride` values apart)
  // into the image and refreshes the border.
  void CopyFrom(const void* src, ptrdiff_t src_row_stride);
  // Copies the pixels (without border) into `dst`, rows `dst_row_stride` values apart.
  void CopyTo(void* dst, ptrdiff_t dst_row_stride) const;
  // Replicates the edge pixels into the border (call after writing pixels directly).
  void FillBorder();
  // Channel value at pixel (x, y) as double, for tests and tools (not for inner loops).
  double Value(int x, int y, int channel = 0) const;
  // A deep copy (copying an Image shares its pixels; see below).
  Image Clone() const;

 private:
  ptrdiff_t Offset(int x, int y) const {
    return (static_cast<ptrdiff_t>(y) + border_) * row_stride_ +
           (static_cast<ptrdiff_t>(x) + border_) * channels_;
  }

  int width_ = 0;
  int height_ = 0;
  int channels_ = 0;
  int border_ = 0;
  PixelType type_ = PixelType::kU8;
  ptrdiff_t row_stride_ = 0;
  size_t bytes_ = 0;
  // Copies of an Image share these pixels (so copying a light field is cheap); writing through
  // one copy changes the others. Clone() makes an independent image.
  std::shared_ptr<unsigned char[]> data_;
};

// Luminance weights: ITU-R BT.601 (Rec. 601) luma, Y = 0.299 R + 0.587 G + 0.114 B. Chosen over
// Rec. 709 because it is what OpenCV (cvtColor RGB2GRAY), Pillow (convert("L")) and scikit-image's
// older rgb2gray use, so a grey reference made by those tools compares like for like; false-colour
// thermal palettes are not colorimetric, so neither weighting is "truer" for them.
constexpr double kLumaR = 0.299, kLumaG = 0.587, kLumaB = 0.114;

// One-channel luminance of `image` in its own pixel type and with its border: 3 or 4 channels
// (RGB, RGBA: alpha is dropped) -> kLumaR R + kLumaG G + kLumaB B (integers rounded to nearest);
// 1 or 2 channels (grey, grey + alpha) -> channel 0. Integer and float images alike.
Image LuminanceImage(const Image& image);

// Describes the first non-finite value of a float image ("pixel (x, y) channel c is NaN"), or
// nullopt when all are finite (always for integer images). Views are checked with it when made.
std::optional<std::string> DescribeNonFinite(const Image& image);

}  // namespace aos
