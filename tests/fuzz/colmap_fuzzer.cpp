// libFuzzer harness: COLMAP sparse models (aos::ReadColmapModel, sfm/colmap_model.h), built
// twice: AOS_FUZZ_COLMAP_EXTENSION ".bin" (binary model) and ".txt" (text model).
//
// One input holds the three files, cameras, images and points3D in that order, separated by
// aos_fuzz::kFileSeparator (missing parts are empty files). Every camera of a model that reads
// is also mapped to its aos lens (LensFromColmapCamera), as the import does next.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "aos/sfm/colmap_model.h"
#include "fuzz_util.h"

#ifndef AOS_FUZZ_COLMAP_EXTENSION
#error "define AOS_FUZZ_COLMAP_EXTENSION as \".bin\" or \".txt\""
#endif

namespace {
constexpr const char* kHarness =
    std::string_view(AOS_FUZZ_COLMAP_EXTENSION) == ".bin" ? "colmap_binary" : "colmap_text";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize(kHarness);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path dir = aos_fuzz::WorkDir(kHarness) / "sparse";
  aos_fuzz::fs::create_directories(dir);
  const char* names[] = {"cameras", "images", "points3D"};
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::string_view separator(aos_fuzz::kFileSeparator);
  size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    size_t end = i < 2 ? input.find(separator, start) : std::string_view::npos;
    if (end == std::string_view::npos) end = input.size();
    const std::string_view part = start <= input.size() ? input.substr(start, end - start)
                                                        : std::string_view();
    aos_fuzz::WriteBytes(dir / (std::string(names[i]) + AOS_FUZZ_COLMAP_EXTENSION),
                         reinterpret_cast<const uint8_t*>(part.data()), part.size());
    start = end + separator.size();
  }
  aos::ColmapModel model;
  if (!aos_fuzz::Expect("ReadColmapModel", [&] { model = aos::ReadColmapModel(dir.string()); })) {
    return 0;
  }
  for (const aos::ColmapCamera& camera : model.cameras) {
    aos_fuzz::Expect("LensFromColmapCamera",
                     [&] { aos::LensFromColmapCamera(camera, model.cameras_path); });
  }
  return 0;
}
