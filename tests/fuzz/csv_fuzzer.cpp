// libFuzzer harness: the CSV readers, built twice: AOS_FUZZ_CSV "telemetry" (the flight log of
// import-telemetry: aos::ImportTelemetry with telemetry_file set, sfm/telemetry.h) and
// "positions" (the name,x,y,z / lat,lon,alt file of import-colmap --positions-file and poses:
// aos::ReadPositionsFile, sfm/colmap_pipeline.h).
//
// Telemetry: the input is the CSV; the frames are four 8 x 6 fixture frames (0000.png ..
// 0003.png, copied into a folder of their own at start-up), the camera a 60-degree pinhole and
// the frame interval 1 s (so that logs with a time column are read too). Positions: the input is
// the file, read once without a CRS and once with EPSG:32633 stated (the first byte of the input
// picks which, so both paths are reached from one corpus).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "aos/sfm/colmap_pipeline.h"
#include "aos/sfm/telemetry.h"
#include "fuzz_util.h"

#ifndef AOS_FUZZ_CSV
#error "define AOS_FUZZ_CSV as \"telemetry\" or \"positions\""
#endif

namespace {
constexpr bool kTelemetry = std::string_view(AOS_FUZZ_CSV) == "telemetry";
constexpr const char* kHarness = kTelemetry ? "telemetry_csv" : "positions_csv";

const aos_fuzz::fs::path& FramesDir() {
  static const aos_fuzz::fs::path frames = [] {
    const aos_fuzz::fs::path dir = aos_fuzz::WorkDir(kHarness) / "frames";
    aos_fuzz::fs::create_directories(dir);
    for (const char* name : {"0000.png", "0001.png", "0002.png", "0003.png"}) {
      aos_fuzz::fs::copy_file(aos_fuzz::WorkDir(kHarness) / "views" / name, dir / name,
                              aos_fuzz::fs::copy_options::overwrite_existing);
    }
    return dir;
  }();
  return frames;
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  aos_fuzz::Initialize(kHarness);
  FramesDir();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const aos_fuzz::fs::path path = aos_fuzz::WorkDir(kHarness) / "log.csv";
  aos_fuzz::WriteBytes(path, data, size);
  if (kTelemetry) {
    aos::TelemetryOptions options;
    options.telemetry_file = path.string();
    options.fov_deg = 60.0;
    options.frame_interval_s = 1.0;
    aos_fuzz::Expect("ImportTelemetry",
                     [&] { aos::ImportTelemetry(FramesDir().string(), options); });
  } else {
    const std::string crs = size > 0 && (data[0] & 1) ? "EPSG:32633" : "";
    aos_fuzz::Expect("ReadPositionsFile", [&] { aos::ReadPositionsFile(path.string(), crs); });
  }
  return 0;
}
