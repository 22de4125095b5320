// libFuzzer harness: light-field files, the aos format and JKU poses.json
// (aos::LoadLightField, lightfield/formats.h). Inputs name the fixture frames of fuzz_util.h.
//
// Each input is loaded headers-only (load_images = false: poses, cameras and the frames' headers
// checked against them) and, when that succeeds, again with the frames decoded, which adds
// CheckLightField. fov_deg is given so JKU files get past their first check.
#include <cstddef>
#include <cstdint>

#include "aos/lightfield/formats.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize("lightfield");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path path = aos_fuzz::WorkDir("lightfield") / "input.json";
  aos_fuzz::WriteBytes(path, data, size);
  aos::LoadOptions options;
  options.fov_deg = 50.0;
  options.num_threads = 1;
  options.load_images = false;
  const bool headers_ok =
      aos_fuzz::Expect("LoadLightField(load_images=false)",
                       [&] { aos::LoadLightField(path.string(), options); });
  if (headers_ok) {
    options.load_images = true;
    aos_fuzz::Expect("LoadLightField(load_images=true)",
                     [&] { aos::LoadLightField(path.string(), options); });
  }
  return 0;
}
