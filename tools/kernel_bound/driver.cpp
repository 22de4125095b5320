// Times the F0 integral render with one build of the AVX2 span kernel: loads F0 once, renders
// the plane z = Z with T threads R times and prints the CPU and wall milliseconds (best and
// median), the samples a second and a hash of the image's bits (variants that must not change
// the image print the kernel's hash). Linked against a copy of libaos_core.a whose kernel object
// was compiled with one of variants.patch's K4 values (run.sh). A measuring tool, not a test.
// Usage: driver F0_POSES_JSON Z THREADS REPEATS
#include <aos/lightfield/formats.h>
#include <aos/render/integral.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <ctime>
#include <vector>

namespace {
double Seconds(clockid_t clock) {
  timespec t;
  clock_gettime(clock, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}
// FNV-1a over the image's rows (float32 bits).
uint64_t ImageHash(const aos::Image& image) {
  uint64_t hash = 1469598103934665603ull;
  for (int y = 0; y < image.height(); ++y) {
    const auto* row = static_cast<const unsigned char*>(image.RawAt(0, y));
    for (size_t i = 0; i < static_cast<size_t>(image.width()) * image.channels() * sizeof(float);
         ++i) {
      hash = (hash ^ row[i]) * 1099511628211ull;
    }
  }
  return hash;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: %s F0_POSES_JSON Z THREADS REPEATS\n", argv[0]);
    return 2;
  }
  aos::LoadOptions load;
  load.fov_deg = 50.815436217896945;  // F0's field of view (tools/bench_integral.py)
  const aos::LoadResult loaded = aos::LoadLightField(argv[1], load);
  aos::IntegralOptions options;
  options.pose_view = 191;
  options.fov_deg = load.fov_deg;
  options.width = options.height = 512;
  options.focal_surface = aos::FocalSurface::FromPlane(aos::Plane::AtHeight(std::atof(argv[2])));
  options.num_threads = std::atoi(argv[3]);
  const int repeats = std::max(1, std::atoi(argv[4]));
  aos::IntegralResult result = aos::RenderIntegral(loaded.light_field, options);  // warm-up
  std::vector<double> cpu, wall;
  for (int i = 0; i < repeats; ++i) {
    const double c = Seconds(CLOCK_PROCESS_CPUTIME_ID), w = Seconds(CLOCK_MONOTONIC);
    result = aos::RenderIntegral(loaded.light_field, options);
    cpu.push_back(Seconds(CLOCK_PROCESS_CPUTIME_ID) - c);
    wall.push_back(Seconds(CLOCK_MONOTONIC) - w);
  }
  std::sort(cpu.begin(), cpu.end());
  std::sort(wall.begin(), wall.end());
  const double median = wall[repeats / 2];
  std::printf("cpu best %6.1f median %6.1f ms, wall best %6.1f median %6.1f ms, %.3f G samples/s, "
              "image %016llx\n",
              cpu[0] * 1e3, cpu[repeats / 2] * 1e3, wall[0] * 1e3, median * 1e3,
              static_cast<double>(result.samples) / median / 1e9,
              static_cast<unsigned long long>(ImageHash(result.image)));
  return 0;
}
