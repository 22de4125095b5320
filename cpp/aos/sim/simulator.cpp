#include "aos/sim/simulator.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

#include <embree3/rtcore.h>

#include "aos/sim/occluders.h"
#include "aos/sim/random.h"
#include "aos/util/error.h"
#include "aos/util/math.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"
#include "aos/util/timer.h"

namespace aos {
namespace {

using sim::Hash;
using sim::Random;
using sim::Stream;

constexpr float kInf = std::numeric_limits<float>::infinity();
// Offset of secondary-ray origins from the surface they leave, metres (well above float
// resolution at the coordinates a scene uses, well below any feature size).
constexpr double kSurfaceOffset = 1e-3;

enum Material : int { kNone = -1, kGround = 0, kTarget = 1, kVoxel = 2, kLeaf = 3, kTrunk = 4 };

Rgb Lerp(const Rgb& a, const Rgb& b, double t) {
  return Rgb{a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t};
}

double Luminance(const Rgb& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// ---- Textures ----

class TextureSampler {
 public:
  TextureSampler(const TextureSpec& spec, uint32_t seed) : spec_(spec), seed_(seed) {
    if (spec.kind == TextureSpec::Kind::kImage) {
      const Image& image = *spec.image;
      width_ = image.width();
      height_ = image.height();
      pixels_.resize(static_cast<size_t>(width_) * height_);
      const double scale = 1.0 / PixelTypeFullRange(image.type());
      for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
          Rgb c;
          for (int k = 0; k < 3; ++k) {
            const int channel = image.channels() >= 3 ? k : 0;
            c[k] = std::clamp(image.Value(x, y, channel) * scale, 0.0, 1.0);
          }
          pixels_[static_cast<size_t>(y) * width_ + x] = c;
        }
      }
    }
  }

  // The pattern at (x, y), metres.
  Rgb operator()(double x, double y) const {
    using Kind = TextureSpec::Kind;
    switch (spec_.kind) {
      case Kind::kConstant:
        return spec_.color_a;
      case Kind::kChecker:
        return Checker(x, y, spec_.square);
      case Kind::kChart: {
        const int64_t i = static_cast<int64_t>(std::floor(x / spec_.patch));
        const int64_t j = static_cast<int64_t>(std::floor(y / spec_.patch));
        const int64_t n = static_cast<int64_t>(spec_.squares.size());
        const int64_t k = (((i + j) % n) + n) % n;
        return Checker(x, y, spec_.squares[static_cast<size_t>(k)]);
      }
      case Kind::kNoise: {
        const double gx = x / spec_.square, gy = y / spec_.square;
        const double fx = std::floor(gx), fy = std::floor(gy);
        const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
        auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
        const double tx = smooth(gx - fx), ty = smooth(gy - fy);
        auto lattice = [&](int64_t a, int64_t b) {
          return sim::ToUniform(Hash(seed_ ^ spec_.seed, Stream::kTexture, static_cast<uint64_t>(a),
                                     static_cast<uint64_t>(b)));
        };
        const double v = (1 - ty) * ((1 - tx) * lattice(ix, iy) + tx * lattice(ix + 1, iy)) +
                         ty * ((1 - tx) * lattice(ix, iy + 1) + tx * lattice(ix + 1, iy + 1));
        return Lerp(spec_.color_a, spec_.color_b, v);
      }
      case Kind::kImage: {
        // Image top at +y; bilinear between pixel centres, tiled.
        double u = x / spec_.size[0], v = y / spec_.size[1];
        u -= std::floor(u);
        v -= std::floor(v);
        const double px = u * width_ - 0.5, py = (1.0 - v) * height_ - 0.5;
        const double fx = std::floor(px), fy = std::floor(py);
        const double ax = px - fx, ay = py - fy;
        auto wrap = [](int64_t i, int n) { return static_cast<int>(((i % n) + n) % n); };
        const int x0 = wrap(static_cast<int64_t>(fx), width_), x1 = wrap(static_cast<int64_t>(fx) + 1, width_);
        const int y0 = wrap(static_cast<int64_t>(fy), height_), y1 = wrap(static_cast<int64_t>(fy) + 1, height_);
        const Rgb top = Lerp(At(x0, y0), At(x1, y0), ax);
        const Rgb bottom = Lerp(At(x0, y1), At(x1, y1), ax);
        return Lerp(top, bottom, ay);
      }
    }
    return spec_.color_a;
  }

 private:
  Rgb Checker(double x, double y, double square) const {
    const int64_t parity = static_cast<int64_t>(std::floor(x / square)) +
                           static_cast<int64_t>(std::floor(y / square));
    return (parity & 1) == 0 ? spec_.color_a : spec_.color_b;
  }
  const Rgb& At(int x, int y) const { return pixels_[static_cast<size_t>(y) * width_ + x]; }

  TextureSpec spec_;
  uint32_t seed_;
  int width_ = 0;
  int height_ = 0;
  std::vector<Rgb> pixels_;
};

// ---- Embree ----

struct DeviceDeleter {
  void operator()(RTCDeviceTy* device) const { rtcReleaseDevice(device); }
};
struct SceneDeleter {
  void operator()(RTCSceneTy* scene) const { rtcReleaseScene(scene); }
};
using DevicePtr = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using ScenePtr = std::unique_ptr<RTCSceneTy, SceneDeleter>;

// Cells per axis of the grid a height-field ground is traced on over `extent`: ceil(extent /
// cell_size), at least 1. GroundHeightfield uses the same grid. Throws beyond 4096 per axis.
std::pair<int, int> GroundGridCells(const GroundSpec& g, const std::array<double, 4>& extent,
                                    const std::string& source) {
  const double nx_real = std::ceil((extent[2] - extent[0]) / g.cell_size);
  const double ny_real = std::ceil((extent[3] - extent[1]) / g.cell_size);
  constexpr double kMaxCells = 4096;
  if (nx_real > kMaxCells || ny_real > kMaxCells) {
    ThrowInvalid(Where(source, "/ground/cell_size: " + FormatNumber(g.cell_size) + " m over a " +
                                   FormatNumber(extent[2] - extent[0]) + " x " +
                                   FormatNumber(extent[3] - extent[1]) +
                                   " m extent needs more than 4096 x 4096 cells; use a larger "
                                   "cell_size or a smaller ground.extent"));
  }
  return {std::max(1, static_cast<int>(nx_real)), std::max(1, static_cast<int>(ny_real))};
}

void CheckEmbree(RTCDevice device, const char* what) {
  const RTCError error = rtcGetDeviceError(device);
  if (error == RTC_ERROR_NONE) return;
  if (error == RTC_ERROR_OUT_OF_MEMORY) {
    throw std::runtime_error(std::string("Embree ran out of memory while ") + what);
  }
  throw std::runtime_error(std::string("Embree error ") + std::to_string(error) + " while " + what);
}

// Ray against an axis-aligned box (slab test), robust for zero direction components and rays
// through edges and corners. Returns the entry distance in [tnear, tfar] and the entry axis.
bool IntersectBox(const float org[3], const float dir[3], const Vec3d& lo, const Vec3d& hi,
                  float tnear, float tfar, float* t_hit, int* axis_hit) {
  double t0 = tnear, t1 = tfar;
  int axis = -1;
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0.0f) {
      if (org[a] < lo[a] || org[a] > hi[a]) return false;
      continue;
    }
    const double inv = 1.0 / dir[a];
    double ta = (lo[a] - org[a]) * inv, tb = (hi[a] - org[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    if (ta > t0) {
      t0 = ta;
      axis = a;
    }
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  if (axis < 0) axis = 2;  // the ray starts inside the box: report the z face
  *t_hit = static_cast<float>(t0);
  *axis_hit = axis;
  return true;
}

void VoxelBounds(const RTCBoundsFunctionArguments* args) {
  const VoxelGrid& grid = *static_cast<const VoxelGrid*>(args->geometryUserPtr);
  const Vec3d lo = grid.CellMin(grid.cells[args->primID]);
  const Vec3d hi = lo + grid.cell;
  RTCBounds* b = args->bounds_o;
  b->lower_x = static_cast<float>(lo.x);
  b->lower_y = static_cast<float>(lo.y);
  b->lower_z = static_cast<float>(lo.z);
  b->upper_x = static_cast<float>(hi.x);
  b->upper_y = static_cast<float>(hi.y);
  b->upper_z = static_cast<float>(hi.z);
}

void VoxelIntersect(const RTCIntersectFunctionNArguments* args) {
  const VoxelGrid& grid = *static_cast<const VoxelGrid*>(args->geometryUserPtr);
  const Vec3d lo = grid.CellMin(grid.cells[args->primID]);
  const Vec3d hi = lo + grid.cell;
  RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, args->N);
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    const float org[3] = {RTCRayN_org_x(ray, args->N, i), RTCRayN_org_y(ray, args->N, i),
                          RTCRayN_org_z(ray, args->N, i)};
    const float dir[3] = {RTCRayN_dir_x(ray, args->N, i), RTCRayN_dir_y(ray, args->N, i),
                          RTCRayN_dir_z(ray, args->N, i)};
    float t;
    int axis;
    if (!IntersectBox(org, dir, lo, hi, RTCRayN_tnear(ray, args->N, i),
                      RTCRayN_tfar(ray, args->N, i), &t, &axis)) {
      continue;
    }
    RTCRayN_tfar(ray, args->N, i) = t;
    float normal[3] = {0, 0, 0};
    normal[axis] = dir[axis] > 0 ? -1.0f : 1.0f;
    RTCHitN_Ng_x(hit, args->N, i) = normal[0];
    RTCHitN_Ng_y(hit, args->N, i) = normal[1];
    RTCHitN_Ng_z(hit, args->N, i) = normal[2];
    RTCHitN_u(hit, args->N, i) = 0.0f;
    RTCHitN_v(hit, args->N, i) = 0.0f;
    RTCHitN_primID(hit, args->N, i) = args->primID;
    RTCHitN_geomID(hit, args->N, i) = args->geomID;
    RTCHitN_instID(hit, args->N, i, 0) = args->context->instID[0];
  }
}

void VoxelOccluded(const RTCOccludedFunctionNArguments* args) {
  const VoxelGrid& grid = *static_cast<const VoxelGrid*>(args->geometryUserPtr);
  const Vec3d lo = grid.CellMin(grid.cells[args->primID]);
  const Vec3d hi = lo + grid.cell;
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    const float org[3] = {RTCRayN_org_x(args->ray, args->N, i), RTCRayN_org_y(args->ray, args->N, i),
                          RTCRayN_org_z(args->ray, args->N, i)};
    const float dir[3] = {RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                          RTCRayN_dir_z(args->ray, args->N, i)};
    float t;
    int axis;
    if (IntersectBox(org, dir, lo, hi, RTCRayN_tnear(args->ray, args->N, i),
                     RTCRayN_tfar(args->ray, args->N, i), &t, &axis)) {
      RTCRayN_tfar(args->ray, args->N, i) = -kInf;
    }
  }
}

struct Hit {
  double t = std::numeric_limits<double>::infinity();
  Vec3d point{0.0};
  // Unit and facing the incoming ray on the ground, and on every surface when the scene has a
  // sun (its only other use); elsewhere Embree's unnormalised geometric normal.
  Vec3d normal{0.0, 0.0, 1.0};
  int material = kNone;
  uint32_t prim = 0;
};

// Per-thread counters, summed at the end.
struct Counters {
  int64_t primary = 0;
  int64_t shadow = 0;
  int64_t noise = 0;
};

// The traceable world: Embree scenes for what needs one, analytic ground otherwise, textures
// and materials for shading.
class World {
 public:
  World(const Scene& scene, const std::array<double, 4>& footprint, SimulationStats* stats)
      : scene_(scene),
        ground_texture_(scene.ground.texture, scene.seed) {
    for (const TargetSpec& target : scene.targets) target_textures_.emplace_back(target.texture, scene.seed);
    const double slope_x = scene.ground.slope[0], slope_y = scene.ground.slope[1];
    plane_normal_ = glm::normalize(Vec3d(-slope_x, -slope_y, 1.0));
    if (scene.effects.sun) {
      const double az = scene.effects.sun_spec.azimuth_deg * kPi / 180.0;
      const double el = scene.effects.sun_spec.elevation_deg * kPi / 180.0;
      sun_ = Vec3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    }
    const bool need_device = scene.HasOccluders() || scene.ground.IsHeightField();
    if (!need_device) return;
    device_.reset(rtcNewDevice(nullptr));
    if (!device_) throw std::runtime_error("Embree: cannot create a device");
    if (scene.HasOccluders()) BuildOccluders(footprint, stats);
    if (scene.ground.IsHeightField()) BuildGround(footprint, stats);
  }

  bool HasOccluderBvh() const { return static_cast<bool>(occluders_); }
  bool HasGroundBvh() const { return static_cast<bool>(ground_); }
  // Whether anything can block a ray between two points above the ground.
  bool CanBlock(bool with_occluders) const { return (with_occluders && occluders_) || ground_; }

  // First surface along o + t d (d unit), t in (0, inf).
  Hit Trace(const Vec3d& o, const Vec3d& d, bool with_occluders) const {
    Hit hit;
    TracePacket(o, &d, 1, with_occluders, &hit);
    return hit;
  }

  // Trace() for n rays from one origin, as packets of kPacket rays (rtcIntersect8). Coherent
  // packets are what make Embree fast here: the caller orders the rays so that each run of
  // kPacket holds neighbouring pixels.
  static constexpr int kPacket = 8;
  void TracePackets(const Vec3d& o, const Vec3d* d, int n, bool with_occluders, Hit* hits) const {
    for (int first = 0; first < n; first += kPacket) {
      TracePacket(o, d + first, std::min(kPacket, n - first), with_occluders, hits + first);
    }
  }

  // Whether the segment o + t d, t in (0, t_max), hits anything (d unit).
  bool Occluded(const Vec3d& o, const Vec3d& d, double t_max, bool with_occluders) const {
    const float tfar = static_cast<float>(std::min<double>(t_max, kInf));
    if (with_occluders && occluders_) {
      RTCRay ray = MakeRayHit(o, d, tfar).ray;
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      rtcOccluded1(occluders_.get(), &context, &ray);
      if (ray.tfar < 0.0f) return true;
    }
    if (ground_) {
      RTCRay ray = MakeRayHit(o, d, tfar).ray;
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      rtcOccluded1(ground_.get(), &context, &ray);
      return ray.tfar < 0.0f;
    }
    return PlaneDistance(o, d) < t_max;
  }

  // The linear value of a hit in [0, 1] (RGB); shadow rays are counted in `counters`.
  Rgb Shade(const Hit& hit, bool with_occluders, Counters* counters) const {
    if (hit.material == kNone) return Rgb{0, 0, 0};
    const bool thermal = scene_.effects.thermal;
    const ThermalSpec& th = scene_.effects.thermal_spec;
    Rgb base;
    switch (hit.material) {
      case kGround:
      case kTarget: {
        Rgb texture;
        if (hit.material == kGround) {
          texture = ground_texture_(hit.point.x, hit.point.y);
        } else {
          double u, v;
          InTarget(scene_.targets[hit.prim], hit.point, &u, &v);
          texture = target_textures_[hit.prim](u, v);
        }
        if (thermal) {
          const double e = hit.material == kGround ? th.ground : th.targets;
          const double value = e + th.texture_contrast * (Luminance(texture) - 0.5);
          base = Rgb{value, value, value};
        } else {
          base = texture;
        }
        break;
      }
      case kVoxel: {
        const double f = 1.0 + scene_.voxels.albedo_variation *
                                   (2.0 * sim::ToUniform(Hash(scene_.seed, Stream::kShade, hit.prim)) - 1.0);
        base = thermal ? Rgb{th.voxels, th.voxels, th.voxels} : Scale(scene_.voxels.albedo, f);
        break;
      }
      case kLeaf:
        base = thermal ? Rgb{th.leaves, th.leaves, th.leaves}
                       : Scale(scene_.trees.leaf_albedo, trees_.brightness[hit.prim]);
        break;
      case kTrunk:
        base = thermal ? Rgb{th.trunks, th.trunks, th.trunks} : scene_.trees.trunk_albedo;
        break;
      default:
        base = Rgb{0, 0, 0};
    }
    if (!scene_.effects.sun) return Clamp(base);
    // Sun: direct light times visibility, plus ambient (albedo); heating (thermal).
    const double cosine = glm::dot(hit.normal, sun_);
    double direct = 0.0;
    if (cosine > 0.0) {
      ++counters->shadow;
      const Vec3d origin = hit.point + kSurfaceOffset * hit.normal;
      if (!Occluded(origin, sun_, std::numeric_limits<double>::infinity(), with_occluders)) {
        direct = cosine;
      }
    }
    if (thermal) {
      const double add = th.sun_heating * direct;
      return Clamp(Rgb{base[0] + add, base[1] + add, base[2] + add});
    }
    const double ambient = scene_.effects.sun_spec.ambient;
    return Clamp(Scale(base, ambient + (1.0 - ambient) * direct));
  }

  int64_t OccluderBytes() const {
    return static_cast<int64_t>(voxels_.cells.capacity() * sizeof(uint32_t) +
                                trees_.vertices.size() * 12 + trees_.quads.size() * 16 +
                                trees_.brightness.size() * 4);
  }

 private:
  static Rgb Scale(const Rgb& c, double f) { return Rgb{c[0] * f, c[1] * f, c[2] * f}; }
  static Rgb Clamp(const Rgb& c) {
    return Rgb{std::clamp(c[0], 0.0, 1.0), std::clamp(c[1], 0.0, 1.0), std::clamp(c[2], 0.0, 1.0)};
  }

  // Traces `count` <= kPacket rays as one packet.
  void TracePacket(const Vec3d& o, const Vec3d* d, int count, bool with_occluders, Hit* hits) const {
    alignas(32) int valid[kPacket];
    alignas(32) RTCRayHit8 rh;
    for (int i = 0; i < kPacket; ++i) {
      valid[i] = i < count ? -1 : 0;
      const Vec3d& di = d[i < count ? i : 0];
      rh.ray.org_x[i] = static_cast<float>(o.x);
      rh.ray.org_y[i] = static_cast<float>(o.y);
      rh.ray.org_z[i] = static_cast<float>(o.z);
      rh.ray.dir_x[i] = static_cast<float>(di.x);
      rh.ray.dir_y[i] = static_cast<float>(di.y);
      rh.ray.dir_z[i] = static_cast<float>(di.z);
      rh.ray.tnear[i] = 0.0f;
      rh.ray.time[i] = 0.0f;
      rh.ray.mask[i] = 0xffffffffu;
      rh.ray.id[i] = static_cast<unsigned>(i);
      rh.ray.flags[i] = 0;
    }
    for (int i = 0; i < count; ++i) hits[i] = Hit();
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    const auto reset = [&rh](int i, float tfar) {
      rh.ray.tfar[i] = tfar;
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    };
    if (with_occluders && occluders_) {
      for (int i = 0; i < kPacket; ++i) reset(i, kInf);
      rtcIntersect8(valid, occluders_.get(), &context, &rh);
      for (int i = 0; i < count; ++i) {
        if (rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
        Hit& hit = hits[i];
        hit.t = rh.ray.tfar[i];
        hit.prim = rh.hit.primID[i];
        if (rh.hit.geomID[i] == voxel_geometry_) {
          hit.material = kVoxel;
        } else {
          hit.material = rh.hit.primID[i] < static_cast<unsigned>(trees_.leaf_quads) ? kLeaf : kTrunk;
        }
        hit.normal = Vec3d(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]);
      }
    }
    if (ground_) {
      for (int i = 0; i < kPacket; ++i) {
        reset(i, i < count ? static_cast<float>(std::min<double>(hits[i].t, kInf)) : kInf);
      }
      rtcIntersect8(valid, ground_.get(), &context, &rh);
    }
    for (int i = 0; i < count; ++i) {
      Hit& hit = hits[i];
      double t_ground = std::numeric_limits<double>::infinity();
      Vec3d ground_normal = plane_normal_;
      if (ground_) {
        if (rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID) {
          t_ground = rh.ray.tfar[i];
          ground_normal = Vec3d(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]);
        }
      } else {
        t_ground = PlaneDistance(o, d[i]);
      }
      if (t_ground < hit.t) {
        hit.t = t_ground;
        hit.normal = ground_normal;
        hit.material = kGround;
      }
      if (hit.material != kNone) Finish(o, d[i], &hit);
    }
  }

  static RTCRayHit MakeRayHit(const Vec3d& o, const Vec3d& d, float tfar) {
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(o.x);
    rh.ray.org_y = static_cast<float>(o.y);
    rh.ray.org_z = static_cast<float>(o.z);
    rh.ray.dir_x = static_cast<float>(d.x);
    rh.ray.dir_y = static_cast<float>(d.y);
    rh.ray.dir_z = static_cast<float>(d.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = tfar;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
  }

  // Distance to the (tilted) ground plane, infinity if the ray runs parallel to it or away.
  double PlaneDistance(const Vec3d& o, const Vec3d& d) const {
    const GroundSpec& g = scene_.ground;
    const double denominator = d.z - g.slope[0] * d.x - g.slope[1] * d.y;
    const double numerator = g.height + g.slope[0] * o.x + g.slope[1] * o.y - o.z;
    if (denominator == 0.0) return std::numeric_limits<double>::infinity();
    const double t = numerator / denominator;
    return t > 0.0 && std::isfinite(t) ? t : std::numeric_limits<double>::infinity();
  }

  // Completes a hit: point, unit normal facing the ray where it is used, target lookup on the
  // ground.
  void Finish(const Vec3d& o, const Vec3d& d, Hit* hit) const {
    hit->point = o + hit->t * d;
    if (hit->material != kGround && !scene_.effects.sun) return;
    const double length = glm::length(hit->normal);
    hit->normal = length > 0.0 ? hit->normal / length : Vec3d(0, 0, 1);
    if (glm::dot(hit->normal, d) > 0.0) hit->normal = -hit->normal;
    if (hit->material != kGround) return;
    for (size_t i = 0; i < scene_.targets.size(); ++i) {
      double u, v;
      if (InTarget(scene_.targets[i], hit->point, &u, &v)) {
        hit->material = kTarget;
        hit->prim = static_cast<uint32_t>(i);
        return;
      }
    }
  }

  static bool InTarget(const TargetSpec& target, const Vec3d& p, double* u, double* v) {
    const double angle = target.rotation_deg * kPi / 180.0;
    const double dx = p.x - target.center[0], dy = p.y - target.center[1];
    const double lx = std::cos(angle) * dx + std::sin(angle) * dy;
    const double ly = -std::sin(angle) * dx + std::cos(angle) * dy;
    *u = lx + 0.5 * target.size[0];
    *v = ly + 0.5 * target.size[1];
    return *u >= 0.0 && *u < target.size[0] && *v >= 0.0 && *v < target.size[1];
  }

  void BuildOccluders(const std::array<double, 4>& footprint, SimulationStats* stats) {
    RTCDevice device = device_.get();
    occluders_.reset(rtcNewScene(device));
    rtcSetSceneFlags(occluders_.get(), RTC_SCENE_FLAG_ROBUST);
    // A high-quality (SAH, spatial splits for quads) build costs tens of milliseconds here and
    // pays back many times over millions of rays: +10 % on the forest, +30 % on the voxels.
    rtcSetSceneBuildQuality(occluders_.get(), RTC_BUILD_QUALITY_HIGH);
    if (scene_.has_voxels) {
      voxels_ = MakeVoxelGrid(scene_.voxels, scene_.seed);
      stats->voxels = static_cast<int64_t>(voxels_.cells.size());
      stats->nadir_blocked_fraction = voxels_.NadirBlockedFraction();
      if (!voxels_.cells.empty()) {
        RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(voxels_.cells.size()));
        rtcSetGeometryUserData(geometry, &voxels_);
        rtcSetGeometryBoundsFunction(geometry, VoxelBounds, nullptr);
        rtcSetGeometryIntersectFunction(geometry, VoxelIntersect);
        rtcSetGeometryOccludedFunction(geometry, VoxelOccluded);
        rtcCommitGeometry(geometry);
        voxel_geometry_ = rtcAttachGeometry(occluders_.get(), geometry);
        rtcReleaseGeometry(geometry);
      }
    }
    if (scene_.has_trees) {
      std::array<double, 4> area = scene_.trees.area;
      if (area == std::array<double, 4>{0, 0, 0, 0}) area = footprint;
      trees_ = MakeTrees(scene_.trees, scene_.ground, area, scene_.seed);
      stats->trees = trees_.trees;
      stats->leaf_quads = trees_.leaf_quads;
      stats->trunk_quads = trees_.trunk_quads;
      if (!trees_.quads.empty()) {
        RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_QUAD);
        auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
            geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
            trees_.vertices.size()));
        auto* quads = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
            geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(uint32_t),
            trees_.quads.size()));
        CheckEmbree(device, "allocating the tree mesh");
        std::copy(trees_.vertices.front().data(), trees_.vertices.front().data() + 3 * trees_.vertices.size(), vertices);
        std::copy(trees_.quads.front().data(), trees_.quads.front().data() + 4 * trees_.quads.size(), quads);
        rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_HIGH);
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(occluders_.get(), geometry);
        rtcReleaseGeometry(geometry);
      }
    }
    rtcCommitScene(occluders_.get());
    CheckEmbree(device, "building the occluder BVH");
    stats->occluder_bvh = true;
  }

  void BuildGround(const std::array<double, 4>& footprint, SimulationStats* stats) {
    const GroundSpec& g = scene_.ground;
    std::array<double, 4> extent = g.extent;
    if (extent == std::array<double, 4>{0, 0, 0, 0}) extent = footprint;
    const auto [nx, ny] = GroundGridCells(g, extent, scene_.source);
    RTCDevice device = device_.get();
    ground_.reset(rtcNewScene(device));
    rtcSetSceneFlags(ground_.get(), RTC_SCENE_FLAG_ROBUST);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_GRID);
    const size_t vertex_count = static_cast<size_t>(nx + 1) * (ny + 1);
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count));
    auto* grid = static_cast<RTCGrid*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_GRID, 0, RTC_FORMAT_GRID, sizeof(RTCGrid), 1));
    CheckEmbree(device, "allocating the ground grid");
    const double dx = (extent[2] - extent[0]) / nx, dy = (extent[3] - extent[1]) / ny;
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        const double x = extent[0] + i * dx, y = extent[1] + j * dy;
        float* v = vertices + 3 * (static_cast<size_t>(j) * (nx + 1) + i);
        v[0] = static_cast<float>(x);
        v[1] = static_cast<float>(y);
        v[2] = static_cast<float>(g.HeightAt(x, y));
      }
    }
    grid->startVertexID = 0;
    grid->stride = static_cast<unsigned>(nx + 1);
    grid->width = static_cast<unsigned short>(nx + 1);
    grid->height = static_cast<unsigned short>(ny + 1);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(ground_.get(), geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(ground_.get());
    CheckEmbree(device, "building the ground BVH");
    stats->ground_bvh = true;
    stats->ground_cells = static_cast<int64_t>(nx) * ny;
  }

  const Scene& scene_;
  TextureSampler ground_texture_;
  std::vector<TextureSampler> target_textures_;
  Vec3d plane_normal_{0, 0, 1};
  Vec3d sun_{0, 0, 1};
  DevicePtr device_;
  ScenePtr occluders_;
  ScenePtr ground_;
  VoxelGrid voxels_;
  TreeMesh trees_;
  unsigned voxel_geometry_ = RTC_INVALID_GEOMETRY_ID;
};

// Bounding box [xmin, ymin, xmax, ymax] of what the views and the truth camera see of the ground
// (nadir footprints on the ground's height range, with a 10 % margin).
std::array<double, 4> Footprint(const Scene& scene, const std::vector<Vec3d>& cameras,
                                const std::vector<double>& tan_half_fov_x,
                                const std::vector<double>& tan_half_fov_y) {
  std::array<double, 4> box{std::numeric_limits<double>::infinity(),
                            std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity()};
  double steps = 0.0;
  for (const StepSpec& step : scene.ground.steps) steps += std::abs(step.height);
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Vec3d& c = cameras[i];
    const double slope = std::abs(scene.ground.slope[0]) + std::abs(scene.ground.slope[1]);
    const double depth = (c.z - scene.ground.HeightAt(c.x, c.y) + steps) * (1.0 + slope);
    const double hx = 1.1 * depth * tan_half_fov_x[i], hy = 1.1 * depth * tan_half_fov_y[i];
    box[0] = std::min(box[0], c.x - hx);
    box[1] = std::min(box[1], c.y - hy);
    box[2] = std::max(box[2], c.x + hx);
    box[3] = std::max(box[3], c.y + hy);
  }
  return box;
}

// The largest angle from the optical axis that a lens camera's frame sees (over its border
// pixels; a fisheye's image circle ends at theta_max), capped at 70 degrees: the extent of the
// occluders and height field built around the views (beyond it, the plane ground only).
double LensFootprintAngle(const LensCamera& lens) {
  constexpr double kCap = 70.0 * kPi / 180.0;
  double angle = 0.0;
  const auto visit = [&](double u, double v) {
    Vec3d ray;
    angle = std::max(angle, lens.Unproject(Vec2d(u, v), &ray)
                                ? std::acos(std::clamp(ray.z / glm::length(ray), -1.0, 1.0))
                                : lens.theta_max);
  };
  for (int x = 0; x <= lens.width; ++x) {
    visit(x, 0.0);
    visit(x, lens.height);
  }
  for (int y = 0; y <= lens.height; ++y) {
    visit(0.0, y);
    visit(lens.width, y);
  }
  return std::min(angle, kCap);
}

// A small rotation exp([w]_x) (Rodrigues).
Mat3d RotationFromVector(const Vec3d& w) {
  const double angle = glm::length(w);
  if (angle == 0.0) return Mat3d(1.0);
  const Vec3d k = w / angle;
  const Mat3d kx = MatFromRows(Vec3d(0, -k.z, k.y), Vec3d(k.z, 0, -k.x), Vec3d(-k.y, k.x, 0));
  return Mat3d(1.0) + std::sin(angle) * kx + (1.0 - std::cos(angle)) * (kx * kx);
}

// Stores a linear value in [0, 1] (float views: unclamped) into the views' type.
void Store(Image& image, int x, int y, int channel, double value) {
  switch (image.type()) {
    case PixelType::kU8:
      image.At<uint8_t>(x, y)[channel] = static_cast<uint8_t>(
          std::lround(std::clamp(value, 0.0, 1.0) * PixelTypeMax<uint8_t>()));
      break;
    case PixelType::kU16:
      image.At<uint16_t>(x, y)[channel] = static_cast<uint16_t>(
          std::lround(std::clamp(value, 0.0, 1.0) * PixelTypeMax<uint16_t>()));
      break;
    default:
      image.At<float>(x, y)[channel] = static_cast<float>(value);
  }
}

PixelType ViewType(int bit_depth) {
  return bit_depth == 8 ? PixelType::kU8 : bit_depth == 16 ? PixelType::kU16 : PixelType::kF32;
}

// The views' cameras, where they are, and the truth camera: what the later stages share.
struct SimCameras {
  LensCamera lens;                 // the views' lens (model kPinhole: traced as pinholes)
  bool through_lens = false;       // rays go through `lens`, not the pinhole `camera`
  PinholeCamera camera;            // the views' pinhole intrinsics
  std::vector<Vec3d> positions;    // the views' centres, world metres
  Vec3d truth_position{0.0};       // the truth camera's centre
  PinholeCamera truth_camera;
  std::array<double, 4> footprint;  // what all of them see of the ground (see Footprint)
};

// The views' horizontal field of view, degrees: the scene's fov_deg, or for explicit
// intrinsics the pinhole field of view of their fx (`camera`: the views' pinhole intrinsics).
double ViewsFovDeg(const CameraSpec& spec, const PinholeCamera& camera) {
  return spec.fx > 0.0 ? camera.FovXDeg() : spec.fov_deg;
}

// Stage 1: the cameras. Refuses a scene whose views would not fit in memory.
SimCameras PlaceCameras(const Scene& scene, SimulationStats* stats) {
  const CameraSpec& cam = scene.camera;
  // A lens camera traces each pixel's rays through the lens model (unprojected exactly, no
  // resampling); pixels outside its valid field (a fisheye's image circle) trace nothing and
  // stay 0. Its view keeps the pinhole intrinsics in View::camera and the lens in View::lens.
  const LensCamera lens = ViewLens(scene);
  const bool through_lens = !lens.IsPinhole();
  PinholeCamera camera;
  if (through_lens || cam.fx > 0.0) {
    camera = lens.Pinhole();
  } else {
    camera = PinholeCamera::FromFov(cam.width, cam.height, cam.fov_deg);
  }
  const std::vector<Vec3d> positions = ViewPositions(scene);
  stats->views = static_cast<int64_t>(positions.size());
  // The views dominate what the simulation keeps; refuse a scene the machine cannot hold before
  // tracing any of it.
  CheckMemoryBudget(
      SaturatingProduct({static_cast<uint64_t>(positions.size()),
                         static_cast<uint64_t>(camera.width), static_cast<uint64_t>(camera.height),
                         static_cast<uint64_t>(cam.channels),
                         static_cast<uint64_t>(cam.bit_depth / 8)}),
      scene.source + ": sampling/camera: " + std::to_string(positions.size()) + " views of " +
          std::to_string(camera.width) + " x " + std::to_string(camera.height) + " pixels",
      "the views' samples");
  Vec3d truth_position(scene.truth.position[0], scene.truth.position[1], scene.truth.position[2]);
  if (std::isnan(truth_position.x)) {
    truth_position = Vec3d(0.0);
    for (const Vec3d& p : positions) truth_position += p;
    truth_position /= static_cast<double>(positions.size());
    if (scene.sampling.positions.empty()) {
      truth_position.x = scene.sampling.center[0];
      truth_position.y = scene.sampling.center[1];
    }
  }
  const bool wide_lens = !TraitsOf(lens.model).perspective;  // fisheye, omnidir
  const PinholeCamera truth_camera = PinholeCamera::FromFov(
      scene.truth.width > 0 ? scene.truth.width : cam.width,
      scene.truth.height > 0 ? scene.truth.height : cam.height,
      scene.truth.fov_deg > 0 ? scene.truth.fov_deg
                              : (wide_lens ? std::min(ViewsFovDeg(cam, camera), 100.0)
                                           : ViewsFovDeg(cam, camera)));
  std::vector<Vec3d> all_cameras = positions;
  std::vector<double> tan_x(positions.size(), 0.5 * cam.width / camera.fx);
  std::vector<double> tan_y(positions.size(), 0.5 * cam.height / camera.fy);
  if (through_lens) {
    const double tan_half = std::tan(LensFootprintAngle(lens));
    std::fill(tan_x.begin(), tan_x.end(), tan_half);
    std::fill(tan_y.begin(), tan_y.end(), tan_half);
  }
  all_cameras.push_back(truth_position);
  tan_x.push_back(0.5 * truth_camera.width / truth_camera.fx);
  tan_y.push_back(0.5 * truth_camera.height / truth_camera.fy);
  SimCameras cameras;
  cameras.lens = lens;
  cameras.through_lens = through_lens;
  cameras.camera = camera;
  cameras.positions = positions;
  cameras.truth_position = truth_position;
  cameras.truth_camera = truth_camera;
  cameras.footprint = Footprint(scene, all_cameras, tan_x, tan_y);
  return cameras;
}

// Stage 3: the recorded poses, the true ones with pose noise when the scene has it.
std::vector<Rigid3d> RecordedPoses(const Scene& scene, const std::vector<Vec3d>& positions,
                                   const std::vector<Rigid3d>& true_cam_from_world,
                                   SimulationStats* stats) {
  std::vector<Rigid3d> recorded = true_cam_from_world;
  if (scene.effects.pose_noise) {
    const double sigma_m = scene.effects.pose_noise_spec.position_sigma_cm / 100.0;
    const double sigma_rad = scene.effects.pose_noise_spec.rotation_sigma_deg * kPi / 180.0;
    for (size_t v = 0; v < positions.size(); ++v) {
      Random random(Hash(scene.seed, Stream::kPoseNoise, v));
      Vec3d dp, w;
      for (int k = 0; k < 3; ++k) dp[k] = sigma_m * random.Normal();
      for (int k = 0; k < 3; ++k) w[k] = sigma_rad * random.Normal();
      stats->pose_noise_draws += 6;
      Rigid3d& pose = recorded[v];
      const Vec3d centre = pose.Center() + dp;
      pose.rotation = RotationFromVector(w) * pose.rotation;
      pose.translation = -(pose.rotation * centre);
    }
  }
  return recorded;
}

// Stage 4: the views, traced from the true poses and stored with the recorded ones.
void TraceViews(const Scene& scene, const World& world, const SimCameras& cameras,
                const std::vector<Rigid3d>& recorded, int threads, ProgressSink* progress,
                SimulationResult& result) {
  const CameraSpec& cam = scene.camera;
  const LensCamera& lens = cameras.lens;
  const bool through_lens = cameras.through_lens;
  const PinholeCamera& camera = cameras.camera;
  const std::vector<Vec3d>& positions = cameras.positions;
  SimulationStats& stats = result.stats;
  const PixelType type = ViewType(cam.bit_depth);
  const int spp = cam.samples_per_pixel;
  const int channels = cam.channels;
  const double sigma = scene.effects.sensor_noise ? scene.effects.sensor_noise_spec.sigma : 0.0;
  ProgressStart(progress, "views", static_cast<int64_t>(positions.size()));
  const Timer timer;
  // The views are traced in tiles of kTileX x kTileY pixels, whose rays go to Embree as packets
  // of 8 (4 x 2 pixels at one sample per pixel): packets of neighbours in both directions stay
  // coherent longer than runs along a row (measured on the forest: 9-10 M rays/s as row streams,
  // 11-12 M as 4 x 4 tiles, with the BVH built at high quality). Unit ray directions in the camera frame are the same for every view; they are computed once when
  // they fit in kDirectionCacheBytes (else per tile), in single precision either way (Embree
  // traces in single precision), so the output does not depend on which path ran.
  constexpr int kTileX = 4, kTileY = 4;
  constexpr size_t kDirectionCacheBytes = size_t{256} << 20;
  const int per_pixel = spp * spp;
  // A zero direction marks a lens sample outside the valid field: no ray, value 0.
  const auto camera_direction = [&](int x, int y, int k) {
    const Vec2d pixel(x + ((k % spp) + 0.5) / spp, y + ((k / spp) + 0.5) / spp);
    if (!through_lens) return glm::vec3(glm::normalize(camera.Unproject(pixel)));
    Vec3d ray;
    return lens.Unproject(pixel, &ray) ? glm::vec3(glm::normalize(ray)) : glm::vec3(0.0f);
  };
  const size_t ray_count = static_cast<size_t>(cam.width) * cam.height * per_pixel;
  std::vector<glm::vec3> direction_cache;
  if (ray_count * sizeof(glm::vec3) <= kDirectionCacheBytes) {
    direction_cache.resize(ray_count);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t y = 0; y < cam.height; ++y) {
      for (int x = 0; x < cam.width; ++x) {
        for (int k = 0; k < per_pixel; ++k) {
          direction_cache[(static_cast<size_t>(y) * cam.width + x) * per_pixel + k] =
              camera_direction(x, static_cast<int>(y), k);
        }
      }
    }
  }
  const int tiles_x = (cam.width + kTileX - 1) / kTileX, tiles_y = (cam.height + kTileY - 1) / kTileY;
  const int64_t tile_count = static_cast<int64_t>(tiles_x) * tiles_y;
  Counters totals;
  result.light_field.views.reserve(positions.size());
  for (size_t v = 0; v < positions.size(); ++v) {
    if (ProgressCancelled(progress)) throw Cancelled();
    const Rigid3d& pose = result.true_cam_from_world[v];
    const Mat3d world_from_cam_rotation = glm::transpose(pose.rotation);
    const Vec3d centre = positions[v];
    Image image(cam.width, cam.height, channels, type, /*border=*/1);
    Counters view_counters;
#pragma omp parallel num_threads(threads)
    {
      Counters local;
      std::vector<Vec3d> directions(static_cast<size_t>(kTileX) * kTileY * per_pixel);
      std::vector<Hit> hits(directions.size());
      std::vector<int> slots(directions.size());  // sample -> traced ray, -1 = none (lens)
      const Hit no_hit;
#pragma omp for schedule(dynamic, 4)
      for (int64_t tile = 0; tile < tile_count; ++tile) {
        const int x0 = static_cast<int>(tile % tiles_x) * kTileX;
        const int y0 = static_cast<int>(tile / tiles_x) * kTileY;
        const int x1 = std::min(x0 + kTileX, cam.width), y1 = std::min(y0 + kTileY, cam.height);
        // The tile's rays, pixel by pixel in row-major order, samples row-major within a pixel.
        size_t n = 0, samples = 0;
        for (int y = y0; y < y1; ++y) {
          for (int x = x0; x < x1; ++x) {
            for (int k = 0; k < per_pixel; ++k) {
              const Vec3d d(direction_cache.empty()
                                ? camera_direction(x, y, k)
                                : direction_cache[(static_cast<size_t>(y) * cam.width + x) *
                                                      per_pixel + k]);
              if (d == Vec3d(0.0)) {
                slots[samples++] = -1;
                continue;
              }
              slots[samples++] = static_cast<int>(n);
              directions[n++] = world_from_cam_rotation * d;
            }
          }
        }
        world.TracePackets(centre, directions.data(), static_cast<int>(n),
                           /*with_occluders=*/true, hits.data());
        local.primary += static_cast<int64_t>(n);
        const int* slot = slots.data();
        for (int y = y0; y < y1; ++y) {
          for (int x = x0; x < x1; ++x) {
            Rgb sum{0, 0, 0};
            bool imaged = false;  // some sample lies in the lens's valid field
            for (int k = 0; k < per_pixel; ++k, ++slot) {
              imaged = imaged || *slot >= 0;
              const Rgb c = world.Shade(*slot >= 0 ? hits[*slot] : no_hit, true, &local);
              for (int channel = 0; channel < 3; ++channel) sum[channel] += c[channel];
            }
            const double inv = 1.0 / per_pixel;
            const Rgb mean{sum[0] * inv, sum[1] * inv, sum[2] * inv};
            for (int k = 0; k < channels; ++k) {
              double value = channels == 1 ? Luminance(mean) : mean[k];
              // No sensor behind pixels outside the image circle: they stay exactly 0.
              if (scene.effects.sensor_noise && imaged) {
                const uint64_t pixel_index = static_cast<uint64_t>(y) * cam.width + x;
                Random random(Hash(scene.seed, Stream::kSensorNoise, v, pixel_index, k));
                value += sigma * random.Normal();
                ++local.noise;
              }
              Store(image, x, y, k, value);
            }
          }
        }
      }
#pragma omp critical
      {
        view_counters.primary += local.primary;
        view_counters.shadow += local.shadow;
        view_counters.noise += local.noise;
      }
    }
    totals.primary += view_counters.primary;
    totals.shadow += view_counters.shadow;
    totals.noise += view_counters.noise;
    image.FillBorder();
    char name[32];
    std::snprintf(name, sizeof(name), "view_%04zu", v);
    result.light_field.views.push_back(
        MakeView(name, through_lens ? lens : LensCamera::FromPinhole(camera), recorded[v], image));
    ProgressAdvance(progress, 1);
  }
  stats.primary_rays = totals.primary;
  stats.lens_rays = through_lens ? totals.primary : 0;
  stats.shadow_rays = totals.shadow;
  stats.sensor_noise_draws = totals.noise;
  stats.seconds_views = timer.Seconds();
}

// Stage 5: the ground truth: the ground alone, seen by the truth camera.
void RenderTruth(const Scene& scene, const World& world, const SimCameras& cameras, int threads,
                 ProgressSink* progress, SimulationResult& result) {
  const CameraSpec& cam = scene.camera;
  const LensCamera& lens = cameras.lens;
  const bool through_lens = cameras.through_lens;
  const PinholeCamera& camera = cameras.camera;
  const std::vector<Vec3d>& positions = cameras.positions;
  const Vec3d& truth_position = cameras.truth_position;
  const PinholeCamera& truth_camera = cameras.truth_camera;
  const PixelType type = ViewType(cam.bit_depth);
  const int spp = cam.samples_per_pixel;
  const int channels = cam.channels;
  SimulationStats& stats = result.stats;
  GroundTruth& truth = result.truth;
  truth.camera = truth_camera;
  truth.cam_from_world = NadirCamFromWorld(truth_position);
  truth.ground_height_at_center = scene.ground.HeightAt(truth_position.x, truth_position.y);
  const int tw = truth_camera.width, th = truth_camera.height;
  truth.ground = Image(tw, th, channels, type);
  truth.depth = Image(tw, th, 1, PixelType::kF32);
  truth.height = Image(tw, th, 1, PixelType::kF32);
  truth.views_seeing = Image(tw, th, 1, PixelType::kU32);
  truth.has_blocked_fraction = scene.truth.blocked_fraction;
  if (truth.has_blocked_fraction) truth.blocked_fraction = Image(tw, th, 1, PixelType::kF32);
  const Mat3d truth_rotation = glm::transpose(truth.cam_from_world.rotation);
  const bool blocked_rays = truth.has_blocked_fraction && world.CanBlock(true);
  ProgressStart(progress, "ground truth", th);
  const Timer timer;
  std::atomic<bool> cancelled{false};
  int64_t truth_rays = 0, truth_shadow = 0, fraction_rays = 0;
  double seconds_fraction = 0.0;
#pragma omp parallel num_threads(threads) reduction(+ : truth_rays, truth_shadow, fraction_rays)
  {
    Counters local;
#pragma omp for schedule(dynamic, 2)
    for (int64_t y = 0; y < th; ++y) {
      if (cancelled.load(std::memory_order_relaxed)) continue;
      for (int x = 0; x < tw; ++x) {
        // Ground image: the same sampling as the views.
        Rgb sum{0, 0, 0};
        for (int sy = 0; sy < spp; ++sy) {
          for (int sx = 0; sx < spp; ++sx) {
            const Vec2d pixel(x + (sx + 0.5) / spp, static_cast<double>(y) + (sy + 0.5) / spp);
            const Vec3d d = glm::normalize(truth_rotation * truth_camera.Unproject(pixel));
            const Hit hit = world.Trace(truth_position, d, /*with_occluders=*/false);
            ++truth_rays;
            const Rgb c = world.Shade(hit, false, &local);
            for (int k = 0; k < 3; ++k) sum[k] += c[k];
          }
        }
        const double inv = 1.0 / (spp * spp);
        const Rgb mean{sum[0] * inv, sum[1] * inv, sum[2] * inv};
        for (int k = 0; k < channels; ++k) {
          Store(truth.ground, x, static_cast<int>(y), k, channels == 1 ? Luminance(mean) : mean[k]);
        }
        // Depth, height, views seeing and blocked: at the pixel centre.
        const Vec3d d = glm::normalize(truth_rotation *
                                       truth_camera.Unproject(Vec2d(x + 0.5, y + 0.5)));
        const Hit hit = world.Trace(truth_position, d, false);
        ++truth_rays;
        float depth = 0.0f, height = 0.0f, fraction = 0.0f;
        uint32_t seeing = 0;
        if (hit.material != kNone) {
          depth = static_cast<float>(glm::dot(d, truth_rotation[2]) * hit.t);
          height = static_cast<float>(hit.point.z);
          uint32_t blocked = 0;
          const Vec3d origin = hit.point + kSurfaceOffset * hit.normal;
          for (size_t v = 0; v < positions.size(); ++v) {
            const Vec3d in_cam = result.true_cam_from_world[v] * hit.point;
            if (!through_lens && !(in_cam.z > 0.0)) continue;
            Vec2d uv;
            if (through_lens) {
              if (!lens.Project(in_cam, &uv)) continue;
            } else {
              uv = camera.Project(in_cam);
            }
            if (!(uv.x >= 0.0 && uv.x <= camera.width && uv.y >= 0.0 && uv.y <= camera.height)) continue;
            ++seeing;
            if (!blocked_rays) continue;
            const Vec3d to_view = positions[v] - origin;
            const double distance = glm::length(to_view);
            ++fraction_rays;
            if (world.Occluded(origin, to_view / distance, distance, true)) ++blocked;
          }
          if (seeing > 0) fraction = static_cast<float>(static_cast<double>(blocked) / seeing);
        }
        *truth.depth.At<float>(x, static_cast<int>(y)) = depth;
        *truth.height.At<float>(x, static_cast<int>(y)) = height;
        *truth.views_seeing.At<uint32_t>(x, static_cast<int>(y)) = seeing;
        if (truth.has_blocked_fraction) *truth.blocked_fraction.At<float>(x, static_cast<int>(y)) = fraction;
      }
      ProgressAdvance(progress, 1);
      if (omp_get_thread_num() == 0 && ProgressCancelled(progress)) cancelled = true;
    }
    truth_shadow += local.shadow;
  }
  if (cancelled) throw Cancelled();
  const double seconds_truth_total = timer.Seconds();
  // The blocked-fraction rays share the truth loop; split its time by ray count.
  const double total_rays = static_cast<double>(truth_rays + fraction_rays + truth_shadow);
  if (fraction_rays > 0 && total_rays > 0) {
    seconds_fraction = seconds_truth_total * fraction_rays / total_rays;
  }
  stats.truth_rays = truth_rays;
  stats.shadow_rays += truth_shadow;
  stats.blocked_fraction_rays = fraction_rays;
  stats.seconds_blocked_fraction = seconds_fraction;
  stats.seconds_truth = seconds_truth_total - seconds_fraction;
}

}  // namespace

void SimulateOptions::Check() const {
  CheckThreadCount(num_threads);
}

SimulationResult Simulate(const Scene& scene, const SimulateOptions& options,
                          ProgressSink* progress) {
  options.Check();
  scene.Check();
  const int threads = ResolveThreadCount(options.num_threads);
  SimulationResult result;
  SimulationStats& stats = result.stats;
  // 1. Cameras.
  const SimCameras cameras = PlaceCameras(scene, &stats);
  // 2. Geometry (occluders and a height-field ground only when the scene has them).
  ProgressStart(progress, "geometry", 1);
  const Timer timer;
  const World world(scene, cameras.footprint, &stats);
  stats.occluder_bytes = world.OccluderBytes();
  stats.seconds_geometry = scene.HasOccluders() || scene.ground.IsHeightField() ? timer.Seconds() : 0.0;
  ProgressAdvance(progress, 1);
  if (ProgressCancelled(progress)) throw Cancelled();
  // 3. Poses: true ones, then the recorded ones (pose noise).
  result.true_cam_from_world.reserve(cameras.positions.size());
  for (const Vec3d& p : cameras.positions) result.true_cam_from_world.push_back(NadirCamFromWorld(p));
  const std::vector<Rigid3d> recorded =
      RecordedPoses(scene, cameras.positions, result.true_cam_from_world, &stats);
  // 4. Views.
  TraceViews(scene, world, cameras, recorded, threads, progress, result);
  // 5. Ground truth.
  RenderTruth(scene, world, cameras, threads, progress, result);
  return result;
}

Heightfield GroundHeightfield(const Scene& scene, const std::array<double, 4>& extent_in) {
  const GroundSpec& g = scene.ground;
  std::array<double, 4> extent = extent_in;
  if (extent == std::array<double, 4>{0, 0, 0, 0}) extent = g.extent;
  if (extent == std::array<double, 4>{0, 0, 0, 0}) {
    ThrowInvalid(Where(scene.source,
                       "/ground/extent: all zero (the simulator then takes the views' footprint, "
                       "which GroundHeightfield does not know); give an extent"));
  }
  for (double v : extent) {
    if (!std::isfinite(v)) ThrowInvalid(Where(scene.source, "extent: not finite"));
  }
  if (!(extent[2] > extent[0]) || !(extent[3] > extent[1])) {
    ThrowInvalid(Where(scene.source, "extent: [" + FormatNumber(extent[0]) + ", " +
                                         FormatNumber(extent[1]) + ", " + FormatNumber(extent[2]) +
                                         ", " + FormatNumber(extent[3]) +
                                         "] is empty (want xmin < xmax, ymin < ymax)"));
  }
  const auto [nx, ny] = GroundGridCells(g, extent, scene.source);
  // The grid's vertices (BuildGround's x, y) are the raster's pixel centres: column i at
  // x_i = xmin + i dx, row r at y_(ny - r) (row 0 = the largest y, north-up).
  const double dx = (extent[2] - extent[0]) / nx, dy = (extent[3] - extent[1]) / ny;
  Heightfield dem;
  dem.width = nx + 1;
  dem.height = ny + 1;
  dem.geotransform = {extent[0] - 0.5 * dx, dx, 0.0, extent[3] + 0.5 * dy, 0.0, -dy};
  dem.heights.resize(static_cast<size_t>(dem.width) * dem.height);
  for (int row = 0; row < dem.height; ++row) {
    const int j = ny - row;
    const double y = extent[1] + j * dy;
    for (int i = 0; i < dem.width; ++i) {
      const double x = extent[0] + i * dx;
      dem.heights[static_cast<size_t>(row) * dem.width + i] = static_cast<float>(g.HeightAt(x, y));
    }
  }
  dem.Check(scene.source + ": ground");
  return dem;
}

}  // namespace aos
