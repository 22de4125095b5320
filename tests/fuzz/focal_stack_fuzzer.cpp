// libFuzzer harness: focal-stack folders (aos::ReadFocalStack, render/focal_stack.h). The input
// is the folder's stack.json; the slice, count and variance images it may name are the fixtures
// slice_000N.tif, count_000N.tif, variance_000N.tif of fuzz_util.h (8 x 6 pixels).
#include <cstddef>
#include <cstdint>

#include "aos/render/focal_stack.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize("focal_stack");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path dir = aos_fuzz::WorkDir("focal_stack");
  aos_fuzz::WriteBytes(dir / "stack.json", data, size);
  aos_fuzz::Expect("ReadFocalStack", [&] { aos::ReadFocalStack(dir.string()); });
  return 0;
}
