#pragma once
// Counter-based random numbers for the simulator: every draw is a pure function of (seed,
// stream, indices), so results do not depend on thread count or order, and adding one effect
// (its own stream) never changes the draws of another.
#include <cmath>
#include <cstdint>

namespace aos::sim {

// Streams: one per consumer of randomness.
enum class Stream : uint64_t {
  kVoxels = 1,
  kTrees = 2,
  kPoseNoise = 3,
  kSensorNoise = 4,
  kTexture = 5,
  kShade = 6,  // per-primitive brightness variation
};

// SplitMix64 finaliser: a bijective 64-bit mix.
inline uint64_t Mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

inline uint64_t Hash(uint64_t seed, Stream stream, uint64_t a = 0, uint64_t b = 0, uint64_t c = 0) {
  uint64_t h = Mix64(seed ^ (static_cast<uint64_t>(stream) << 56));
  h = Mix64(h ^ a);
  h = Mix64(h ^ (b + 0x632be59bd9b4e019ULL));
  return Mix64(h ^ (c + 0x2545f4914f6cdd1dULL));
}

// Uniform in [0, 1) from the top 53 bits.
inline double ToUniform(uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

// A sequential generator seeded from a hash (for generation loops that draw many numbers).
class Random {
 public:
  explicit Random(uint64_t state) : state_(state) {}
  uint64_t Next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    return Mix64(state_);
  }
  double Uniform() { return ToUniform(Next()); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  // Standard normal (Box-Muller; uses two draws).
  double Normal() {
    const double u1 = 1.0 - Uniform();  // (0, 1]
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  uint64_t state_;
};

}  // namespace aos::sim
