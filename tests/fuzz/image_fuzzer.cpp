// libFuzzer harness: image files through OpenImageIO (aos::ReadImageInfo, ReadGpsTag, ReadImage;
// image/image_io.h), built once per format: AOS_FUZZ_IMAGE_EXTENSION ".png", ".tif", ".exr",
// ".jpg". The extension picks OpenImageIO's first decoder; a file it refuses is offered to the
// others, so every decoder is reachable from each harness.
//
// OpenImageIO and the codec libraries are Debian's, not instrumented: libFuzzer sees coverage of
// aos's code only, and ASan sees their memory errors only where they pass through its
// interceptors (memcpy, malloc, ...). Their crashes (SEGV, abort) are still caught.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_util.h"

#ifndef AOS_FUZZ_IMAGE_EXTENSION
#error "define AOS_FUZZ_IMAGE_EXTENSION, e.g. \".png\""
#endif

namespace {
const std::string kHarness = "image_" + std::string(AOS_FUZZ_IMAGE_EXTENSION).substr(1);
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize(kHarness.c_str());
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path path =
      aos_fuzz::WorkDir(kHarness.c_str()) / (std::string("input") + AOS_FUZZ_IMAGE_EXTENSION);
  aos_fuzz::WriteBytes(path, data, size);
  aos::ImageFileInfo info;
  const bool header_ok =
      aos_fuzz::Expect("ReadImageInfo", [&] { info = aos::ReadImageInfo(path.string()); });
  aos_fuzz::Expect("ReadGpsTag", [&] { aos::ReadGpsTag(path.string()); });
  aos::Image image;
  const bool image_ok =
      aos_fuzz::Expect("ReadImage", [&] { image = aos::ReadImage(path.string(), 1); });
  // A decoded image agrees with its header.
  if (image_ok && header_ok &&
      (image.width() != info.width || image.height() != info.height ||
       image.channels() != info.channels || image.type() != info.type)) {
    aos_fuzz::Finding("ReadImage", "decoded " + std::to_string(image.width()) + "x" +
                                       std::to_string(image.height()) + "x" +
                                       std::to_string(image.channels()) + " " +
                                       aos::PixelTypeName(image.type()) +
                                       " but ReadImageInfo said " + std::to_string(info.width) +
                                       "x" + std::to_string(info.height) + "x" +
                                       std::to_string(info.channels) + " " +
                                       aos::PixelTypeName(info.type));
  }
  return 0;
}
