#include "aos/render/focal_surface.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>

#include <embree3/rtcore.h>
#include <omp.h>

#include "aos/geometry/geodesy.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/parallel.h"

namespace aos {
namespace {

// Embree asserts (aborting the process) on a ray whose origin or direction has a component
// beyond its FLT_LARGE, 1.844e18; rays past this never reach it (they are misses). The rules
// of the contract (kMaxRayCastRadius, kMaxRayOriginDistance) keep every ray far inside it; this
// is the last guard, where no exception may be thrown (inside the OpenMP loops).
constexpr float kEmbreeLargest = 1e18f;

bool EmbreeTakes(float org_x, float org_y, float org_z, float dir_x, float dir_y, float dir_z) {
  for (float v : {org_x, org_y, org_z, dir_x, dir_y, dir_z}) {
    if (!(std::abs(v) <= kEmbreeLargest)) return false;  // also NaN
  }
  return true;
}

// The largest |component| of v.
double MaxNorm(const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

}  // namespace

// What a surface holds: its source data and, for everything but a plane, a triangle mesh ray cast
// through an Embree BVH built on first use.
struct FocalSurface::Impl {
  FocalSurfaceKind kind = FocalSurfaceKind::kPlane;
  Plane plane;
  Mesh mesh;  // mesh, height field triangulation, or a depth map's focal points
  bool mesh_in_local_frame = false;  // true for a depth map's mesh (no origin to subtract)
  Heightfield heightfield;
  Image depth;
  PinholeCamera depth_camera;
  Rigid3d depth_cam_from_world;
  std::string source;
  std::string file;     // the path Read() read it from (empty otherwise)
  Vec3d centroid{0.0};  // of the mesh's vertices (mesh frame), double
  double min_z = 0.0, max_z = 0.0;
  double min_x = 0.0, max_x = 0.0, min_y = 0.0, max_y = 0.0;  // of the vertices (mesh frame)

  mutable std::once_flag bvh_once;
  mutable RTCDevice device = nullptr;
  mutable RTCScene scene = nullptr;
  mutable std::string bvh_error;

  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }

  // The centroid and z range, and the ray cast's rule: every vertex within kMaxRayCastRadius of
  // the centroid (per axis), else std::invalid_argument naming the source and the vertex.
  void Finish() {
    Vec3d sum(0.0);
    min_x = min_y = min_z = std::numeric_limits<double>::infinity();
    max_x = max_y = max_z = -min_z;
    for (const Vec3d& v : mesh.vertices) {
      sum += v;
      min_x = std::min(min_x, v.x);
      max_x = std::max(max_x, v.x);
      min_y = std::min(min_y, v.y);
      max_y = std::max(max_y, v.y);
      min_z = std::min(min_z, v.z);
      max_z = std::max(max_z, v.z);
    }
    centroid = mesh.vertices.empty() ? Vec3d(0.0) : sum / static_cast<double>(mesh.vertices.size());
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Vec3d& v = mesh.vertices[i];
      const double distance = MaxNorm(v - centroid);
      if (!(distance <= kMaxRayCastRadius)) {
        ThrowInvalid(Where(source.empty() ? std::string(FocalSurfaceKindName(kind)) : source,
                           "vertex " + std::to_string(i) + " (" + FormatNumber(v.x) + ", " +
                               FormatNumber(v.y) + ", " + FormatNumber(v.z) + ") lies " +
                               FormatNumber(distance) + " m from the surface's centroid (" +
                               FormatNumber(centroid.x) + ", " + FormatNumber(centroid.y) + ", " +
                               FormatNumber(centroid.z) + "); the float32 ray cast holds " +
                               FormatNumber(kMaxRayCastRadius) + " m at most"));
      }
    }
  }

  // Throws std::invalid_argument naming `what` when a ray from `origin` (mesh frame) lies beyond
  // kMaxRayOriginDistance of the centroid.
  void CheckRayOrigin(const Vec3d& origin, const std::string& what) const {
    const double distance = MaxNorm(origin - centroid);
    if (!(distance <= kMaxRayOriginDistance)) {
      ThrowInvalid(what + " lies " + FormatNumber(distance) + " m from the centroid of the focal " +
                   "surface" + (source.empty() ? std::string() : " " + source) +
                   "; the float32 ray cast holds rays from within " +
                   FormatNumber(kMaxRayOriginDistance) + " m of it");
    }
  }

  // Builds the BVH once (float vertices relative to the centroid).
  RTCScene Scene() const {
    std::call_once(bvh_once, [this] {
      device = rtcNewDevice(nullptr);
      if (device == nullptr) {
        bvh_error = "Embree: cannot create a device";
        return;
      }
      scene = rtcNewScene(device);
      rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
      rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
      RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
          geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
          mesh.vertices.size()));
      auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
          geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
          mesh.triangles.size()));
      if (vertices == nullptr || indices == nullptr) {
        rtcReleaseGeometry(geometry);
        bvh_error = "Embree: out of memory for the mesh's buffers";
        return;
      }
      for (size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Vec3d v = mesh.vertices[i] - centroid;
        vertices[3 * i] = static_cast<float>(v.x);
        vertices[3 * i + 1] = static_cast<float>(v.y);
        vertices[3 * i + 2] = static_cast<float>(v.z);
      }
      for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        for (int k = 0; k < 3; ++k) indices[3 * i + k] = static_cast<unsigned>(mesh.triangles[i][k]);
      }
      rtcCommitGeometry(geometry);
      rtcAttachGeometry(scene, geometry);
      rtcReleaseGeometry(geometry);
      rtcCommitScene(scene);
      if (rtcGetDeviceError(device) != RTC_ERROR_NONE) bvh_error = "Embree: building the BVH failed";
    });
    if (!bvh_error.empty()) throw std::runtime_error(bvh_error);
    return scene;
  }

  // Distance t >= 0 along origin + t direction (mesh frame, double) to the first triangle hit,
  // or NaN. Embree finds the triangle in float; t is recomputed on its plane in double.
  double Cast(RTCScene bvh, const Vec3d& origin, const Vec3d& direction) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rayhit;
    const Vec3d o = origin - centroid;
    rayhit.ray.org_x = static_cast<float>(o.x);
    rayhit.ray.org_y = static_cast<float>(o.y);
    rayhit.ray.org_z = static_cast<float>(o.z);
    rayhit.ray.dir_x = static_cast<float>(direction.x);
    rayhit.ray.dir_y = static_cast<float>(direction.y);
    rayhit.ray.dir_z = static_cast<float>(direction.z);
    rayhit.ray.tnear = 0.0f;
    rayhit.ray.tfar = std::numeric_limits<float>::infinity();
    rayhit.ray.mask = ~0u;
    rayhit.ray.flags = 0;
    rayhit.ray.time = 0.0f;
    rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
    if (!EmbreeTakes(rayhit.ray.org_x, rayhit.ray.org_y, rayhit.ray.org_z, rayhit.ray.dir_x,
                     rayhit.ray.dir_y, rayhit.ray.dir_z)) {
      return std::numeric_limits<double>::quiet_NaN();
    }
    rtcIntersect1(bvh, &context, &rayhit);
    if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::numeric_limits<double>::quiet_NaN();
    return HitDistance(rayhit.hit.primID, rayhit.ray.tfar, origin, direction);
  }

  // The distance along origin + t direction (mesh frame, double) to the plane of the triangle
  // Embree hit (Embree's float distance where that is not a positive number).
  double HitDistance(unsigned triangle_index, float embree_t, const Vec3d& origin,
                     const Vec3d& direction) const {
    const auto& triangle = mesh.triangles[triangle_index];
    const Vec3d& a = mesh.vertices[static_cast<size_t>(triangle[0])];
    const Vec3d normal = glm::cross(mesh.vertices[static_cast<size_t>(triangle[1])] - a,
                                    mesh.vertices[static_cast<size_t>(triangle[2])] - a);
    const double f = glm::dot(normal, direction);
    const double t = f != 0.0 ? glm::dot(normal, a - origin) / f : static_cast<double>(embree_t);
    return std::isfinite(t) && t > 0.0 ? t : static_cast<double>(embree_t);
  }

  // Cast(bvh, origins[k], directions[k]) for k < count <= 8 (coherent rays: those of
  // neighbouring pixels) as one Embree packet, written to t[k]. Embree does not promise that a
  // packet finds the same triangle as a single ray; it may differ only within float rounding of
  // a shared edge, and the distance is recomputed in double on the hit triangle's plane, so the
  // depth agrees to float rounding (focal_surface_test: PacketCast... against a brute-force
  // double-precision cast; on F0 the depth map was bit-identical to single rays).
  void CastPacket(RTCScene bvh, const Vec3d* origins, const Vec3d* directions, int count,
                  double* t) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    RTCRayHit8 rays;
    alignas(32) int valid[8];
    for (int k = 0; k < 8; ++k) {
      const Vec3d& d = directions[k < count ? k : 0];
      const Vec3d o = origins[k < count ? k : 0] - centroid;
      valid[k] = k < count ? -1 : 0;
      rays.ray.org_x[k] = static_cast<float>(o.x);
      rays.ray.org_y[k] = static_cast<float>(o.y);
      rays.ray.org_z[k] = static_cast<float>(o.z);
      rays.ray.dir_x[k] = static_cast<float>(d.x);
      rays.ray.dir_y[k] = static_cast<float>(d.y);
      rays.ray.dir_z[k] = static_cast<float>(d.z);
      rays.ray.tnear[k] = 0.0f;
      rays.ray.tfar[k] = std::numeric_limits<float>::infinity();
      rays.ray.mask[k] = ~0u;
      rays.ray.id[k] = static_cast<unsigned>(k);
      rays.ray.flags[k] = 0;
      rays.ray.time[k] = 0.0f;
      rays.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rays.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
      if (!EmbreeTakes(rays.ray.org_x[k], rays.ray.org_y[k], rays.ray.org_z[k],
                       rays.ray.dir_x[k], rays.ray.dir_y[k], rays.ray.dir_z[k])) {
        valid[k] = 0;  // a miss (the last guard; CastDepth refuses such rays first)
      }
    }
    rtcIntersect8(valid, bvh, &context, &rays);
    for (int k = 0; k < count; ++k) {
      t[k] = valid[k] == 0 || rays.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID
                 ? std::numeric_limits<double>::quiet_NaN()
                 : HitDistance(rays.hit.primID[k], rays.ray.tfar[k], origins[k], directions[k]);
    }
  }

  // The depth map of `camera` at `cam_from_world`: each pixel's ray from `origin` (mesh frame),
  // moved by -offsets[pixel] * up when `offsets` is given, cast in packets of 8 neighbouring
  // pixels of a row (coherent rays: Embree traverses them together); 0 where it misses.
  Image CastDepth(const PinholeCamera& camera, const Rigid3d& cam_from_world, const Vec3d& origin,
                  const Vec3d& up, const std::vector<double>* offsets, int num_threads) const {
    // The rays start at origin - offset * up: the farthest are those of the extreme offsets.
    double lowest = 0.0, highest = 0.0;
    if (offsets != nullptr && !offsets->empty()) {
      const auto [low, high] = std::minmax_element(offsets->begin(), offsets->end());
      lowest = *low;
      highest = *high;
    }
    for (double offset : {lowest, highest}) {
      CheckRayOrigin(origin - offset * up,
                     offsets == nullptr
                         ? "cam_from_world: the virtual camera's centre"
                         : "offsets: the virtual camera's centre moved by an offset of " +
                               FormatNumber(offset) + " m");
    }
    RTCScene bvh = Scene();
    const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
    Image depth(camera.width, camera.height, 1, PixelType::kF32);
    const int threads = ResolveThreadCount(num_threads);
#pragma omp parallel for num_threads(threads) schedule(dynamic, 8)
    for (int64_t y = 0; y < camera.height; ++y) {
      float* row = depth.At<float>(0, static_cast<int>(y));
      for (int x0 = 0; x0 < camera.width; x0 += 8) {
        const int count = std::min(8, camera.width - x0);
        Vec3d origins[8];
        Vec3d directions[8];
        double t[8];
        for (int k = 0; k < count; ++k) {
          directions[k] = world_from_cam *
                          camera.Unproject(Vec2d(x0 + k + 0.5, static_cast<double>(y) + 0.5));
          // Moving the surface by o along up = moving the ray's origin by -o.
          origins[k] = offsets == nullptr
                           ? origin
                           : origin - (*offsets)[static_cast<size_t>(y) * camera.width + x0 + k] * up;
        }
        CastPacket(bvh, origins, directions, count, t);
        for (int k = 0; k < count; ++k) {
          row[x0 + k] = std::isfinite(t[k]) && t[k] > 0.0 ? static_cast<float>(t[k]) : 0.0f;
        }
      }
    }
    return depth;
  }

  // The mesh frame's origin in the local frame, and the shift of the placement: a point p of the
  // mesh frame lies at p + to_local in the local frame.
  Vec3d ToLocal(const SurfacePlacement& placement) const {
    const Vec3d frame_shift = mesh_in_local_frame ? Vec3d(0.0) : WorldToLocal(Vec3d(0.0), placement.origin);
    return frame_shift + placement.offset * placement.up;
  }
};

namespace {

std::shared_ptr<FocalSurface::Impl> NewImpl(FocalSurfaceKind kind) {
  auto impl = std::make_shared<FocalSurface::Impl>();
  impl->kind = kind;
  return impl;
}

const Heightfield kEmptyHeightfield{};
const Image kEmptyImage{};


}  // namespace

const char* FocalSurfaceKindName(FocalSurfaceKind kind) {
  switch (kind) {
    case FocalSurfaceKind::kPlane: return "plane";
    case FocalSurfaceKind::kMesh: return "mesh";
    case FocalSurfaceKind::kHeightfield: return "heightfield";
    case FocalSurfaceKind::kDepthMap: return "depth_map";
  }
  return "?";
}

void SurfacePlacement::Check() const {
  if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z)) {
    ThrowInvalid("origin: must be finite");
  }
  if (!std::isfinite(offset)) ThrowInvalid("surface_offset: must be finite (got " + FormatNumber(offset) + ")");
  for (int k = 0; k < 3; ++k) {
    const std::string problem = SurfaceCoordinateProblem(origin[k]);
    if (!problem.empty()) ThrowInvalid(std::string("origin: ") + "xyz"[k] + " " + problem);
  }
  if (const std::string problem = SurfaceCoordinateProblem(offset); !problem.empty()) {
    ThrowInvalid("surface_offset: " + problem);
  }
  if (!(up.x == 0.0 && up.y == 0.0 && std::abs(up.z) == 1.0)) {
    ThrowInvalid("up: must be (0, 0, 1) or (0, 0, -1)");
  }
}

FocalSurface FocalSurface::FromPlane(const Plane& plane) {
  const double length = glm::length(plane.normal);
  if (!std::isfinite(length) || !(length > 0.0) || !std::isfinite(plane.point.x) ||
      !std::isfinite(plane.point.y) || !std::isfinite(plane.point.z)) {
    ThrowInvalid("focal_surface: plane: point and normal must be finite and the normal non-zero");
  }
  for (int k = 0; k < 3; ++k) {
    const std::string problem = SurfaceCoordinateProblem(plane.point[k]);
    if (!problem.empty()) ThrowInvalid(std::string("focal_surface: plane: point ") + "xyz"[k] + " " + problem);
  }
  auto impl = NewImpl(FocalSurfaceKind::kPlane);
  impl->plane = plane;
  FocalSurface surface;
  surface.impl_ = impl;
  return surface;
}

FocalSurface FocalSurface::FromMesh(Mesh mesh, std::string source) {
  DropDegenerateTriangles(mesh);
  mesh.Check(source);
  auto impl = NewImpl(FocalSurfaceKind::kMesh);
  impl->mesh = std::move(mesh);
  impl->source = std::move(source);
  impl->Finish();
  FocalSurface surface;
  surface.impl_ = impl;
  return surface;
}

FocalSurface FocalSurface::FromHeightfield(Heightfield heightfield, std::string source) {
  if (source.empty()) source = heightfield.source;  // the file it was read from, if any
  auto impl = NewImpl(FocalSurfaceKind::kHeightfield);
  impl->mesh = HeightfieldToMesh(heightfield, source);
  impl->heightfield = std::move(heightfield);
  impl->source = std::move(source);
  impl->Finish();
  FocalSurface surface;
  surface.impl_ = impl;
  return surface;
}

FocalSurface FocalSurface::FromDepthMap(const Image& depth, const PinholeCamera& camera,
                                        const Rigid3d& cam_from_world) {
  camera.Check("depth camera");
  if (depth.type() != PixelType::kF32 || depth.channels() != 1) {
    ThrowInvalid("depth: must be float32 with 1 channel");
  }
  if (depth.width() != camera.width || depth.height() != camera.height) {
    ThrowInvalid("depth: " + std::to_string(depth.width()) + "x" + std::to_string(depth.height()) +
                 " does not match the camera's " + std::to_string(camera.width) + "x" +
                 std::to_string(camera.height));
  }
  if (auto problem = DescribeInvalidRigid(cam_from_world)) ThrowInvalid("cam_from_world: " + *problem);
  auto impl = NewImpl(FocalSurfaceKind::kDepthMap);
  impl->depth = depth.Clone();
  impl->depth_camera = camera;
  impl->depth_cam_from_world = cam_from_world;
  impl->mesh_in_local_frame = true;
  // The focal points, triangulated as a height field of the image grid.
  const int w = camera.width, h = camera.height;
  const Vec3d center = cam_from_world.Center();
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
  std::vector<int> index(static_cast<size_t>(w) * h, -1);
  for (int y = 0; y < h; ++y) {
    const float* row = depth.At<float>(0, y);
    for (int x = 0; x < w; ++x) {
      const double z = row[x];
      if (!(std::isfinite(z) && z > 0.0)) continue;
      const Vec3d point = center + z * (world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5)));
      for (int k = 0; k < 3; ++k) {
        const std::string problem = SurfaceCoordinateProblem(point[k]);
        if (!problem.empty()) {
          ThrowInvalid("depth: pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                       "): depth " + FormatNumber(z) + " m puts its focal point's " + "xyz"[k] +
                       " at a value that " + problem);
        }
      }
      index[static_cast<size_t>(y) * w + x] = static_cast<int>(impl->mesh.vertices.size());
      impl->mesh.vertices.push_back(point);
    }
  }
  for (int y = 0; y + 1 < h; ++y) {
    for (int x = 0; x + 1 < w; ++x) {
      const int a = index[static_cast<size_t>(y) * w + x], b = index[static_cast<size_t>(y) * w + x + 1];
      const int c = index[static_cast<size_t>(y + 1) * w + x], d = index[static_cast<size_t>(y + 1) * w + x + 1];
      if (a < 0 || b < 0 || c < 0 || d < 0) continue;
      impl->mesh.triangles.push_back({a, b, d});
      impl->mesh.triangles.push_back({a, d, c});
    }
  }
  if (impl->mesh.vertices.empty()) ThrowInvalid("depth: no pixel has a finite depth > 0");
  DropDegenerateTriangles(impl->mesh);
  impl->Finish();
  FocalSurface surface;
  surface.impl_ = impl;
  return surface;
}

FocalSurface FocalSurface::Read(const std::string& path) {
  CheckRegularFile(path, "focal surface");
  FocalSurface surface = IsMeshFile(path) ? FromMesh(ReadMesh(path), path)
                                          : FromHeightfield(ReadHeightfield(path), path);
  // The Impl was made just now and is not shared yet.
  std::const_pointer_cast<Impl>(surface.impl_)->file = path;
  return surface;
}

FocalSurface FocalSurface::AsReadFrom(FocalSurface surface, const std::string& file) {
  if (surface.kind() != FocalSurfaceKind::kMesh && surface.kind() != FocalSurfaceKind::kHeightfield) {
    ThrowInvalid("focal surface: only a mesh or a height field is read from a file");
  }
  if (surface.impl_.use_count() > 1) {  // shared: a surface of its own (the data copied)
    surface = surface.kind() == FocalSurfaceKind::kMesh
                  ? FromMesh(surface.mesh(), surface.source())
                  : FromHeightfield(surface.heightfield(), surface.source());
  }
  std::const_pointer_cast<Impl>(surface.impl_)->file = file;  // held by `surface` alone
  return surface;
}

FocalSurfaceKind FocalSurface::kind() const { return impl_->kind; }
const Plane& FocalSurface::plane() const { return impl_->plane; }
const Mesh& FocalSurface::mesh() const { return impl_->mesh; }
const Heightfield& FocalSurface::heightfield() const {
  return impl_->kind == FocalSurfaceKind::kHeightfield ? impl_->heightfield : kEmptyHeightfield;
}
const Image& FocalSurface::depth() const { return impl_->kind == FocalSurfaceKind::kDepthMap ? impl_->depth : kEmptyImage; }
const PinholeCamera& FocalSurface::depth_camera() const { return impl_->depth_camera; }
const Rigid3d& FocalSurface::depth_cam_from_world() const { return impl_->depth_cam_from_world; }
const std::string& FocalSurface::source() const { return impl_->source; }
const std::string& FocalSurface::file() const { return impl_->file; }

std::string FocalSurface::Describe() const {
  const Impl& s = *impl_;
  std::string text = FocalSurfaceKindName(s.kind);
  if (!s.source.empty()) text += " " + s.source;
  switch (s.kind) {
    case FocalSurfaceKind::kPlane:
      return text + " through (" + FormatNumber(s.plane.point.x) + ", " + FormatNumber(s.plane.point.y) +
             ", " + FormatNumber(s.plane.point.z) + ")";
    case FocalSurfaceKind::kHeightfield:
      text += " (" + std::to_string(s.heightfield.width) + " x " + std::to_string(s.heightfield.height) + " pixels, ";
      break;
    case FocalSurfaceKind::kDepthMap:
      text += " (" + std::to_string(s.depth.width()) + " x " + std::to_string(s.depth.height()) + " pixels, ";
      break;
    case FocalSurfaceKind::kMesh:
      text += " (";
      break;
  }
  text += std::to_string(s.mesh.vertices.size()) + " vertices, " + std::to_string(s.mesh.triangles.size()) +
          " triangles";
  if (s.mesh.dropped_triangles > 0) text += ", " + std::to_string(s.mesh.dropped_triangles) + " degenerate dropped";
  return text + ")";
}

bool FocalSurface::SameAs(const FocalSurface& other) const {
  if (impl_ == other.impl_) return true;
  const Impl& a = *impl_;
  const Impl& b = *other.impl_;
  if (a.kind != b.kind) return false;
  switch (a.kind) {
    case FocalSurfaceKind::kPlane:
      return a.plane.point == b.plane.point && a.plane.normal == b.plane.normal;
    case FocalSurfaceKind::kMesh:
      return a.mesh.vertices == b.mesh.vertices && a.mesh.triangles == b.mesh.triangles;
    case FocalSurfaceKind::kHeightfield: {
      const Heightfield& f = a.heightfield;
      const Heightfield& g = b.heightfield;
      if (f.width != g.width || f.height != g.height || f.geotransform != g.geotransform ||
          f.crs_wkt != g.crs_wkt) {
        return false;
      }
      for (size_t i = 0; i < f.heights.size(); ++i) {
        if (!(f.heights[i] == g.heights[i] || (std::isnan(f.heights[i]) && std::isnan(g.heights[i])))) return false;
      }
      return true;
    }
    case FocalSurfaceKind::kDepthMap: {
      const PinholeCamera& c = a.depth_camera;
      const PinholeCamera& d = b.depth_camera;
      if (c.width != d.width || c.height != d.height || c.fx != d.fx || c.fy != d.fy ||
          c.cx != d.cx || c.cy != d.cy ||
          a.depth_cam_from_world.rotation != b.depth_cam_from_world.rotation ||
          a.depth_cam_from_world.translation != b.depth_cam_from_world.translation) {
        return false;
      }
      for (int y = 0; y < c.height; ++y) {
        for (int x = 0; x < c.width; ++x) {
          const float p = a.depth.At<float>(x, y)[0], q = b.depth.At<float>(x, y)[0];
          if (!(p == q || (std::isnan(p) && std::isnan(q)))) return false;
        }
      }
      return true;
    }
  }
  return false;
}

Vec3d FocalSurface::ReferencePoint(const Vec3d& origin) const {
  const Impl& s = *impl_;
  if (s.kind == FocalSurfaceKind::kPlane) return s.plane.point;
  return s.mesh_in_local_frame ? s.centroid : WorldToLocal(s.centroid, origin);
}

std::array<double, 4> FocalSurface::ExtentInWorld(const Vec3d& origin) const {
  const Impl& s = *impl_;
  if (s.kind == FocalSurfaceKind::kPlane) {
    const double inf = std::numeric_limits<double>::infinity();
    return {-inf, -inf, inf, inf};
  }
  const Vec3d shift = s.mesh_in_local_frame ? origin : Vec3d(0.0);
  return {s.min_x + shift.x, s.min_y + shift.y, s.max_x + shift.x, s.max_y + shift.y};
}

Image PlaneDepth(const PinholeCamera& camera, const Rigid3d& cam_from_world, const Plane& plane,
                 int num_threads) {
  Image depth(camera.width, camera.height, 1, PixelType::kF32);
  const Vec3d center = cam_from_world.Center();
  const Vec3d normal = glm::normalize(plane.normal);
  const double h = glm::dot(normal, plane.point - center);
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
#pragma omp parallel for num_threads(ResolveThreadCount(num_threads)) schedule(static)
  for (int y = 0; y < camera.height; ++y) {
    float* row = depth.At<float>(0, y);
    for (int x = 0; x < camera.width; ++x) {
      // The ray C + t D with D = R^T K^-1 p has camera depth t (D's camera z is 1).
      const Vec3d direction = world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double f = glm::dot(normal, direction);
      const double t = f != 0.0 ? h / f : 0.0;
      row[x] = t > 0.0 && std::isfinite(t) ? static_cast<float>(t) : 0.0f;
    }
  }
  return depth;
}

Image FocalSurface::DepthFor(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                             const SurfacePlacement& placement, int num_threads) const {
  placement.Check();
  camera.Check("virtual camera");
  const Impl& s = *impl_;
  if (s.kind == FocalSurfaceKind::kPlane) {
    Plane shifted = s.plane;
    shifted.point += placement.offset * placement.up;
    return PlaneDepth(camera, cam_from_world, shifted, num_threads);
  }
  if (s.kind == FocalSurfaceKind::kDepthMap && placement.offset == 0.0 &&
      camera.width == s.depth_camera.width && camera.height == s.depth_camera.height &&
      camera.fx == s.depth_camera.fx && camera.fy == s.depth_camera.fy &&
      camera.cx == s.depth_camera.cx && camera.cy == s.depth_camera.cy &&
      cam_from_world.rotation == s.depth_cam_from_world.rotation &&
      cam_from_world.translation == s.depth_cam_from_world.translation) {
    return s.depth.Clone();
  }
  // Ray origin in the mesh frame: the local camera centre minus the mesh frame's local position.
  return s.CastDepth(camera, cam_from_world, cam_from_world.Center() - s.ToLocal(placement),
                     placement.up, nullptr, num_threads);
}

Image FocalSurface::DepthForOffsets(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                                    const SurfacePlacement& placement,
                                    const std::vector<double>& offsets, int num_threads) const {
  placement.Check();
  camera.Check("virtual camera");
  const size_t pixels = static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height);
  if (offsets.size() != pixels) {
    ThrowInvalid("offsets: " + std::to_string(offsets.size()) + " entries for " +
                 std::to_string(camera.width) + " x " + std::to_string(camera.height) + " pixels");
  }
  for (size_t i = 0; i < pixels; ++i) {
    if (!std::isfinite(offsets[i])) {
      ThrowInvalid("offsets: entry " + std::to_string(i) + " is not finite");
    }
  }
  const Impl& s = *impl_;
  if (s.kind == FocalSurfaceKind::kPlane) {
    const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
    Image depth(camera.width, camera.height, 1, PixelType::kF32);
    const Vec3d normal = glm::normalize(s.plane.normal);
    const Vec3d point = s.plane.point + placement.offset * placement.up;
    const double h0 = glm::dot(normal, point - cam_from_world.Center());
    const double up_along_normal = glm::dot(normal, placement.up);
    const int threads = ResolveThreadCount(num_threads);
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t y = 0; y < camera.height; ++y) {
      float* row = depth.At<float>(0, static_cast<int>(y));
      for (int x = 0; x < camera.width; ++x) {
        const Vec3d direction =
            world_from_cam * camera.Unproject(Vec2d(x + 0.5, static_cast<double>(y) + 0.5));
        const double f = glm::dot(normal, direction);
        const double h =
            h0 + offsets[static_cast<size_t>(y) * camera.width + x] * up_along_normal;
        const double t = f != 0.0 ? h / f : 0.0;
        row[x] = t > 0.0 && std::isfinite(t) ? static_cast<float>(t) : 0.0f;
      }
    }
    return depth;
  }
  return s.CastDepth(camera, cam_from_world, cam_from_world.Center() - s.ToLocal(placement),
                     placement.up, &offsets, num_threads);
}

std::vector<double> FocalSurface::HeightsAt(const std::vector<Vec2d>& xy_in_world,
                                            const SurfacePlacement& placement) const {
  placement.Check();
  const Impl& s = *impl_;
  std::vector<double> heights(xy_in_world.size(), std::numeric_limits<double>::quiet_NaN());
  const double up_z = placement.up.z;
  if (s.kind == FocalSurfaceKind::kPlane) {
    const Vec3d n = glm::normalize(s.plane.normal);
    const Vec3d point = s.plane.point + placement.origin + placement.offset * placement.up;  // world
    for (size_t i = 0; i < xy_in_world.size(); ++i) {
      if (n.z == 0.0) continue;
      const double dx = xy_in_world[i].x - point.x, dy = xy_in_world[i].y - point.y;
      heights[i] = point.z - (n.x * dx + n.y * dy) / n.z;
    }
    return heights;
  }
  RTCScene bvh = s.Scene();
  // Mesh frame -> world: + (local shift) + origin.
  const Vec3d to_world = s.ToLocal(placement) + placement.origin;
  // Start above the highest point along up (mesh frame).
  const double start_z = (up_z > 0.0 ? s.max_z : s.min_z) + up_z * (1.0 + (s.max_z - s.min_z));
  const Vec3d direction(0.0, 0.0, -up_z);
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < static_cast<int64_t>(xy_in_world.size()); ++i) {
    const Vec3d origin(xy_in_world[static_cast<size_t>(i)].x - to_world.x,
                       xy_in_world[static_cast<size_t>(i)].y - to_world.y, start_z);
    // No vertex lies farther than kMaxRayCastRadius from the centroid in x or y: a vertical line
    // beyond that misses (exactly, and without a float ray far from the surface).
    if (!(std::abs(origin.x - s.centroid.x) <= kMaxRayCastRadius &&
          std::abs(origin.y - s.centroid.y) <= kMaxRayCastRadius)) {
      continue;
    }
    const double t = s.Cast(bvh, origin, direction);
    if (std::isfinite(t)) heights[static_cast<size_t>(i)] = start_z - up_z * t + to_world.z;
  }
  return heights;
}

namespace {

// "EPSG:<code>" of a height field's CRS, or its WKT when it has no EPSG code; "" without one.
std::string HeightfieldCrs(const FocalSurface& surface) {
  if (surface.kind() != FocalSurfaceKind::kHeightfield) return "";
  const std::string& wkt = surface.heightfield().crs_wkt;
  if (wkt.empty()) return "";
  const std::string epsg = EpsgOfCrs(wkt, surface.source().empty() ? "focal surface" : surface.source());
  return epsg.empty() ? wkt : epsg;
}

}  // namespace

std::string SurfaceBehindTheCameras(const FocalSurface& surface, const LightField& light_field) {
  if (light_field.views.empty() || surface.kind() == FocalSurfaceKind::kDepthMap) return "";
  // The side the cameras look to along z: the mean of their viewing directions.
  double look_z = 0.0, camera_lo = std::numeric_limits<double>::infinity();
  double camera_hi = -camera_lo;
  for (const View& view : light_field.views) {
    const Vec3d centre = view.cam_from_world.Center() + light_field.origin;
    if (!std::isfinite(centre.z)) continue;
    look_z += Row(view.cam_from_world.rotation, 2).z;  // the camera's z axis in the world
    camera_lo = std::min(camera_lo, centre.z);
    camera_hi = std::max(camera_hi, centre.z);
  }
  look_z /= static_cast<double>(light_field.views.size());
  if (!(std::abs(look_z) > 0.5) || !std::isfinite(camera_lo)) return "";  // not looking down
  // The surface's world z range: a horizontal plane's height, a mesh's or DEM's vertices.
  double lo = 0.0, hi = 0.0;
  if (surface.kind() == FocalSurfaceKind::kPlane) {
    const Plane& plane = surface.plane();
    const Vec3d normal = glm::normalize(plane.normal);
    if (std::abs(std::abs(normal.z) - 1.0) > 1e-9) return "";
    lo = hi = plane.point.z + light_field.origin.z;
  } else {
    lo = std::numeric_limits<double>::infinity();
    hi = -lo;
    for (const Vec3d& vertex : surface.mesh().vertices) {
      lo = std::min(lo, vertex.z);
      hi = std::max(hi, vertex.z);
    }
    if (!(lo <= hi)) return "";
  }
  // Every camera looks away from the surface: with z up (looking down, look_z < 0) the surface
  // lies above every camera; with z down (JKU's F0) below, which is "above" there too.
  const bool behind = look_z < 0.0 ? lo > camera_hi : hi < camera_lo;
  if (!behind) return "";
  const auto range = [](double a, double b) {
    return a == b ? FormatNumber(a) : FormatNumber(a) + " .. " + FormatNumber(b);
  };
  return "the surface lies above the cameras (behind them, as they look): its world z is " +
         range(lo, hi) + " and the cameras' " + range(camera_lo, camera_hi) +
         (look_z < 0.0 ? "" : " (z pointing down)") +
         "; altitudes above the take-off point (relative) against a terrain's heights? Import "
         "them with altitude_reference 'takeoff' (the take-off ground's height added)";
}

void CheckSurfaceCovers(const FocalSurface& surface, const LightField& light_field,
                        const std::string& what, int64_t uncovered_pixels, int64_t pixels,
                        const std::vector<double>& extent_in_world) {
  if (pixels <= 0 || uncovered_pixels < pixels) return;
  const std::string name = surface.source().empty() ? "focal_surface" : surface.source();
  // The surface behind the cameras first (the cause named outright), then its extent and CRS.
  const std::string behind = SurfaceBehindTheCameras(surface, light_field);
  const bool plane = surface.kind() == FocalSurfaceKind::kPlane;
  std::string message =
      name + ": no pixel is covered: " +
      (!behind.empty() ? behind
       : plane ? "no view sees the plane where " + what + " meets it; check the camera pose, "
                 "view_indices, min_view_count and the masks"
               : "the surface does not cover " + what +
                     " (or no view sees it); check its extent and CRS");
  const std::array<double, 4> box = surface.ExtentInWorld(light_field.origin);
  const auto range = [](double x0, double y0, double x1, double y1) {
    return "x " + FormatNumber(x0) + " .. " + FormatNumber(x1) + ", y " + FormatNumber(y0) +
           " .. " + FormatNumber(y1);
  };
  if (extent_in_world.size() == 4 && std::isfinite(box[0]) &&
      (box[2] < extent_in_world[0] || box[0] > extent_in_world[2] ||
       box[3] < extent_in_world[1] || box[1] > extent_in_world[3])) {
    message += ": it spans " + range(box[0], box[1], box[2], box[3]) + " (world), " + what +
               " " + range(extent_in_world[0], extent_in_world[1], extent_in_world[2],
                           extent_in_world[3]);
  }
  const std::string crs = HeightfieldCrs(surface);
  if (!crs.empty() && light_field.crs.empty()) {
    message += "; the surface is in " + DescribeCrs(crs) +
               " but the light field has none, so its coordinates were taken as the light "
               "field's world frame (origin + local) as they are";
  }
  ThrowInvalid(message);
}

FocalSurface InCrs(const FocalSurface& surface, const std::string& crs) {
  const std::string from = HeightfieldCrs(surface);
  if (from.empty() || crs.empty() || from == crs) return surface;
  const std::string where = surface.source().empty() ? "focal surface" : surface.source();
  Mesh mesh = HeightfieldToMesh(surface.heightfield(), where);
  mesh.vertices = TransformPoints(mesh.vertices, surface.heightfield().crs_wkt, crs, where);
  return FocalSurface::FromMesh(std::move(mesh), where + " (" + from + " -> " + crs + ")");
}

SurfacePlacement ResolveSurfacePlacement(const FocalSurface& surface, const LightField& light_field,
                                         const std::vector<int>& view_indices, double offset) {
  // A DEM in another CRS than the light field's would be read as if it were in the light
  // field's: refuse (InCrs transforms it; the CLI does so itself).
  const std::string dem_crs = HeightfieldCrs(surface);
  if (!dem_crs.empty() && !light_field.crs.empty() && dem_crs != light_field.crs) {
    ThrowInvalid("focal_surface: " + (surface.source().empty() ? "the height field" : surface.source()) +
                 " is in " + DescribeCrs(dem_crs) + " but the light field is in " +
                 DescribeCrs(light_field.crs) +
                 ": move it into the light field's CRS first (FocalSurface::InCrs; aos's Python "
                 "render functions and the CLI do this themselves)");
  }
  SurfacePlacement placement;
  placement.origin = light_field.origin;
  placement.offset = offset;
  Vec3d sum(0.0);
  int count = 0;
  auto add = [&](size_t i) {
    if (i >= light_field.views.size()) return;
    const Vec3d c = light_field.views[i].cam_from_world.Center();
    if (std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z)) {
      sum += c;
      ++count;
    }
  };
  if (view_indices.empty()) {
    for (size_t i = 0; i < light_field.views.size(); ++i) add(i);
  } else {
    for (int i : view_indices) add(static_cast<size_t>(i));
  }
  if (count == 0) ThrowInvalid("focal_surface: no selected view has a finite centre to tell up from");
  const double views_z = sum.z / count;
  const double surface_z = surface.ReferencePoint(placement.origin).z;
  placement.up = Vec3d(0.0, 0.0, views_z < surface_z ? -1.0 : 1.0);
  placement.Check();
  return placement;
}

}  // namespace aos
