#include "aos/image/image.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "aos/util/error.h"

namespace aos {
namespace {
constexpr size_t kSlackBytes = 32;
}  // namespace

double PixelTypeFullRange(PixelType type) {
  switch (type) {
    case PixelType::kU8: return PixelTypeMax<uint8_t>();
    case PixelType::kU16: return PixelTypeMax<uint16_t>();
    case PixelType::kU32: return PixelTypeMax<uint32_t>();
    case PixelType::kF32: return 1.0;
  }
  return 1.0;
}

const char* PixelTypeName(PixelType type) {
  switch (type) {
    case PixelType::kU8: return "uint8";
    case PixelType::kU16: return "uint16";
    case PixelType::kU32: return "uint32";
    case PixelType::kF32: return "float32";
  }
  return "?";
}

PixelType ParsePixelTypeName(const std::string& name, const std::string& where) {
  for (const PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kU32, PixelType::kF32}) {
    if (name == PixelTypeName(type)) return type;
  }
  ThrowInvalid(where + ": expected uint8, uint16, uint32 or float32 (got '" + name + "')");
}

Image::Image(int width, int height, int channels, PixelType type, int border)
    : width_(width), height_(height), channels_(channels), border_(border), type_(type) {
  if (width <= 0 || height <= 0) {
    ThrowInvalid("image: width and height must be positive (got " + std::to_string(width) + "x" +
                 std::to_string(height) + ")");
  }
  if (channels < 1 || channels > 4) {
    ThrowInvalid("image: channels must be 1..4 (got " + std::to_string(channels) + ")");
  }
  if (border < 0) ThrowInvalid("image: border must be >= 0");
  row_stride_ = static_cast<ptrdiff_t>(width + 2 * border) * channels;
  bytes_ = static_cast<size_t>(row_stride_) * (height + 2 * border) * PixelTypeSize(type);
  // Slack past the end: SIMD gathers read 4 bytes at a tap's address, and the 8-bit integral
  // kernel 16 bytes from a tap (integral_kernels_avx2.cpp: FetchU8FromRows).
  data_.reset(new unsigned char[bytes_ + kSlackBytes]());
}

size_t Image::PixelBytes() const {
  return static_cast<size_t>(width_) * height_ * channels_ * PixelTypeSize(type_);
}

void Image::CopyFrom(const void* src, ptrdiff_t src_row_stride) {
  const size_t value_size = PixelTypeSize(type_);
  const size_t row_bytes = static_cast<size_t>(width_) * channels_ * value_size;
  const auto* source = static_cast<const unsigned char*>(src);
  for (int y = 0; y < height_; ++y) {
    std::memcpy(RawAt(0, y), source + static_cast<ptrdiff_t>(y) * src_row_stride * value_size,
                row_bytes);
  }
  FillBorder();
}

void Image::CopyTo(void* dst, ptrdiff_t dst_row_stride) const {
  const size_t value_size = PixelTypeSize(type_);
  const size_t row_bytes = static_cast<size_t>(width_) * channels_ * value_size;
  auto* destination = static_cast<unsigned char*>(dst);
  for (int y = 0; y < height_; ++y) {
    std::memcpy(destination + static_cast<ptrdiff_t>(y) * dst_row_stride * value_size,
                RawAt(0, y), row_bytes);
  }
}

void Image::FillBorder() {
  if (border_ == 0 || empty()) return;
  const size_t pixel_bytes = channels_ * PixelTypeSize(type_);
  // Left and right columns of every image row.
  for (int y = 0; y < height_; ++y) {
    for (int b = 1; b <= border_; ++b) {
      std::memcpy(RawAt(-b, y), RawAt(0, y), pixel_bytes);
      std::memcpy(RawAt(width_ - 1 + b, y), RawAt(width_ - 1, y), pixel_bytes);
    }
  }
  // Whole rows above and below, corners included.
  const size_t full_row_bytes = static_cast<size_t>(row_stride_) * PixelTypeSize(type_);
  for (int b = 1; b <= border_; ++b) {
    std::memcpy(RawAt(-border_, -b), RawAt(-border_, 0), full_row_bytes);
    std::memcpy(RawAt(-border_, height_ - 1 + b), RawAt(-border_, height_ - 1), full_row_bytes);
  }
}

double Image::Value(int x, int y, int channel) const {
  switch (type_) {
    case PixelType::kU8: return At<uint8_t>(x, y)[channel];
    case PixelType::kU16: return At<uint16_t>(x, y)[channel];
    case PixelType::kU32: return At<uint32_t>(x, y)[channel];
    case PixelType::kF32: return At<float>(x, y)[channel];
  }
  return 0.0;
}

Image Image::Clone() const {
  if (empty()) return Image();
  Image copy(width_, height_, channels_, type_, border_);
  std::memcpy(copy.data_.get(), data_.get(), bytes_);
  return copy;
}

namespace {

template <typename T>
void LuminanceRows(const Image& image, Image& grey) {
  const int channels = image.channels();
  for (int y = -image.border(); y < image.height() + image.border(); ++y) {
    const T* in = image.At<T>(-image.border(), y);
    T* out = grey.At<T>(-image.border(), y);
    for (int x = 0; x < image.width() + 2 * image.border(); ++x, in += channels) {
      if (channels < 3) {
        out[x] = in[0];
        continue;
      }
      const double y_value = kLumaR * in[0] + kLumaG * in[1] + kLumaB * in[2];
      if constexpr (std::is_floating_point_v<T>) {
        out[x] = static_cast<T>(y_value);
      } else {
        // The weights sum to 1, so the value stays within the type's range.
        out[x] = static_cast<T>(std::min(std::round(y_value), PixelTypeMax<T>()));
      }
    }
  }
}

}  // namespace

Image LuminanceImage(const Image& image) {
  if (image.empty()) return Image();
  Image grey(image.width(), image.height(), 1, image.type(), image.border());
  switch (image.type()) {
    case PixelType::kU8: LuminanceRows<uint8_t>(image, grey); break;
    case PixelType::kU16: LuminanceRows<uint16_t>(image, grey); break;
    case PixelType::kU32: LuminanceRows<uint32_t>(image, grey); break;
    case PixelType::kF32: LuminanceRows<float>(image, grey); break;
  }
  return grey;
}

std::optional<std::string> DescribeNonFinite(const Image& image) {
  if (image.type() != PixelType::kF32) return std::nullopt;
  for (int y = 0; y < image.height(); ++y) {
    const float* row = image.At<float>(0, y);
    for (int i = 0; i < image.width() * image.channels(); ++i) {
      if (!std::isfinite(row[i])) {
        return "pixel (" + std::to_string(i / image.channels()) + ", " + std::to_string(y) +
               ") channel " + std::to_string(i % image.channels()) + " is " +
               (std::isnan(row[i]) ? "NaN" : "infinite");
      }
    }
  }
  return std::nullopt;
}

}  // namespace aos
