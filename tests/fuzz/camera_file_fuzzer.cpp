// libFuzzer harness: aos-camera files (aos::ReadCameraFile, lightfield/camera_file.h).
#include <cstddef>
#include <cstdint>

#include "aos/lightfield/camera_file.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize("camera_file");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path path = aos_fuzz::WorkDir("camera_file") / "camera.json";
  aos_fuzz::WriteBytes(path, data, size);
  aos_fuzz::Expect("ReadCameraFile", [&] { aos::ReadCameraFile(path.string()); });
  return 0;
}
