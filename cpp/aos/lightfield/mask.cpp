#include "aos/lightfield/mask.h"

#include <algorithm>
#include <cstdint>

#include "aos/image/image_io.h"
#include "aos/util/error.h"

namespace aos {
namespace {

template <typename T>
void MarkValid(const Image& mask, Image& valid) {
  const int colour_channels = mask.channels() >= 3 ? 3 : 1;
  for (int y = 0; y < mask.height(); ++y) {
    const T* in = mask.At<T>(0, y);
    uint8_t* out = valid.At<uint8_t>(0, y);
    for (int x = 0; x < mask.width(); ++x) {
      bool any = false;
      for (int c = 0; c < colour_channels; ++c) any = any || in[c] != T(0);
      out[x] = any ? 1 : 0;
      in += mask.channels();
    }
  }
}

template <typename T>
void Premultiply(const Image& frame, const Image& valid, Image& out) {
  const int channels = frame.channels();
  const T full = static_cast<T>(PixelTypeFullRange(frame.type()));  // 1 for float
  for (int y = 0; y < frame.height(); ++y) {
    const T* in = frame.At<T>(0, y);
    const uint8_t* m = valid.At<uint8_t>(0, y);
    T* o = out.At<T>(0, y);
    for (int x = 0; x < frame.width(); ++x) {
      const bool keep = m[x] != 0;
      for (int c = 0; c < channels; ++c) o[c] = keep ? in[c] : T(0);
      o[channels] = keep ? full : T(0);
      in += channels;
      o += channels + 1;
    }
  }
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

Image ReadMask(const std::string& path) {
  Image mask;
  try {
    mask = ReadImage(path);
  } catch (const std::invalid_argument& error) {
    ThrowInvalid(Where("mask " + path, error.what()));
  }
  Image valid(mask.width(), mask.height(), 1, PixelType::kU8);
  switch (mask.type()) {
    case PixelType::kU8: MarkValid<uint8_t>(mask, valid); break;
    case PixelType::kU16: MarkValid<uint16_t>(mask, valid); break;
    case PixelType::kU32: MarkValid<uint32_t>(mask, valid); break;
    case PixelType::kF32: MarkValid<float>(mask, valid); break;
  }
  return valid;
}

int64_t CountValid(const Image& valid) {
  int64_t count = 0;
  for (int y = 0; y < valid.height(); ++y) {
    const uint8_t* row = valid.At<uint8_t>(0, y);
    count += std::count_if(row, row + valid.width(), [](uint8_t v) { return v != 0; });
  }
  return count;
}

Image ApplyMask(const Image& frame, const Image& valid, const std::string& mask_path,
                const std::string& where) {
  if (frame.channels() > 3) {
    ThrowInvalid(Where(where, "mask: the frame has " + std::to_string(frame.channels()) +
                                  " channels (RGBA); a masked frame takes one more channel for "
                                  "the weight and the renderer takes at most 4: load it grey "
                                  "(LoadOptions::grey) or drop the alpha"));
  }
  if (valid.width() != frame.width() || valid.height() != frame.height()) {
    ThrowInvalid(Where(where, "mask " + mask_path + " is " +
                                  SizeText(valid.width(), valid.height()) + " but the frame is " +
                                  SizeText(frame.width(), frame.height())));
  }
  Image out(frame.width(), frame.height(), frame.channels() + 1, frame.type(), 1);
  switch (frame.type()) {
    case PixelType::kU8: Premultiply<uint8_t>(frame, valid, out); break;
    case PixelType::kU16: Premultiply<uint16_t>(frame, valid, out); break;
    case PixelType::kU32: Premultiply<uint32_t>(frame, valid, out); break;
    case PixelType::kF32: Premultiply<float>(frame, valid, out); break;
  }
  out.FillBorder();
  return out;
}

}  // namespace aos
