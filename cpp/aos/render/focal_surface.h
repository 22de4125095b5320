#pragma once
// Focal surfaces: where the virtual camera's rays are focused. One abstraction for every kind
// the renderer takes (integral.h, focal_stack.h, merge.h): a plane, a triangle mesh (OBJ/PLY,
// geometry/mesh.h), a height field (a DEM raster, geometry/heightfield.h) or a per-pixel depth
// map of a given virtual camera.
//
// Contract
// - Frames. A plane and a depth map are in the light field's LOCAL frame (as IntegralOptions'
//   focal_plane). Meshes and height fields are in WORLD coordinates (world = LightField::origin +
//   local, the frame their files are written in); SurfacePlacement::origin moves them into the
//   local frame (WorldToLocal is the one place that conversion happens, so a CRS transform can
//   be slotted in there).
// - Up. The offset of a surface is measured along "up": +z or -z of the local frame, whichever
//   points from the surface towards the mean centre of the selected views (the cameras are above
//   the ground: geo-referenced light fields have z up, JKU/F0 poses have z DOWN, so up is -z
//   there). The surface's reference point for this is: a plane's point, a mesh's or height
//   field's vertex centroid, a depth map's mean focal point. If the views' mean centre lies
//   exactly at the reference height, up is +z. ResolveSurfacePlacement computes it.
// - An offset d moves the whole surface by d * up ("1.0" = one metre above the terrain).
// - DepthFor: for every pixel of a pinhole virtual camera, z in the camera frame (metres) of the
//   first point where its ray (from the camera centre through the pixel centre, pixel centres at
//   +0.5) meets the surface in front of the camera; 0 where it misses (the renderer then gives
//   the pixel count 0). Meshes and height fields are ray cast with Embree: the BVH is built once
//   per surface (lazily, thread-safe) in float coordinates relative to the vertex centroid, and
//   the hit distance is then recomputed in double precision on the hit triangle's plane, so a
//   flat mesh gives its plane's depth to double rounding (the map is float32). A height field
//   is cast as HeightfieldToMesh's triangles (cells with a nodata corner are holes: misses).
//   A depth map gives itself back for its own camera (same intrinsics, size and pose) with offset
//   0; otherwise it is cast as the mesh of its focal points (two triangles per 2 x 2 pixels with
//   valid depths).
// - HeightsAt: the world z where a vertical ray at world (x, y), coming down from the up side,
//   first meets the (offset) surface; NaN where it misses. For the orthographic map.
// - Coordinates the float32 ray cast can hold. Every coordinate a surface is made of (a vertex,
//   a height, a pixel centre, a plane's point, a depth map's focal point, the placement's origin
//   and offset) lies within +-kMaxSurfaceCoordinate (1e9 m, mesh.h), else std::invalid_argument
//   names the file or field and the vertex, pixel or coordinate. Embree then works in float
//   relative to the surface's vertex centroid: every vertex lies within kMaxRayCastRadius
//   (1e7 m, per axis) of it, refused when the surface is made otherwise, and every ray starts
//   within kMaxRayOriginDistance (1e8 m) of it: DepthFor/DepthForOffsets refuse a camera centre
//   (moved by the offsets) farther away, naming cam_from_world or offsets; HeightsAt's vertical
//   lines beyond kMaxRayCastRadius miss (NaN), as they do geometrically. Why these numbers: float
//   rounds a coordinate r to r * 2^-24, 0.6 m at 1e7 m and 6 m at 1e8 m, so a triangle is still
//   found to within a cell of a coarse DEM (its hit distance is then recomputed in double);
//   Embree's triangle test forms products of three coordinates (1e8^3 = 1e24, far below FLT_MAX
//   3.4e38); and Embree aborts the process (assert ray.valid()) on a ray origin beyond 1.8e18
//   (FLT_LARGE), which 1e20 or 3e38 surfaces made it reach. No ray beyond that is ever cast.
//
// Throws std::invalid_argument naming the file or field for bad surfaces and placements.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "aos/geometry/heightfield.h"
#include "aos/geometry/mesh.h"
#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"
#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"

namespace aos {

// The farthest a surface's vertex may lie from its vertex centroid, per axis, metres (see the
// contract).
inline constexpr double kMaxRayCastRadius = 1e7;
// The farthest a ray cast onto a surface may start from its vertex centroid, per axis, metres.
inline constexpr double kMaxRayOriginDistance = 1e8;

enum class FocalSurfaceKind { kPlane, kMesh, kHeightfield, kDepthMap };

// "plane", "mesh", "heightfield", "depth_map".
const char* FocalSurfaceKindName(FocalSurfaceKind kind);

// Where a surface lies for one render: the light field's origin, the resolved up axis and the
// offset along it.
struct SurfacePlacement {
  Vec3d origin{0.0};       // world position of the local frame's zero (LightField::origin)
  Vec3d up{0.0, 0.0, 1.0};  // unit up direction in the local frame: (0, 0, 1) or (0, 0, -1)
  double offset = 0.0;     // metres along up

  // Throws std::invalid_argument naming the field for a non-finite origin or offset, or an up
  // that is not +-z.
  void Check() const;
};

// World -> local coordinates (world - origin). The one place meshes and height fields enter the
// local frame.
inline Vec3d WorldToLocal(const Vec3d& point_in_world, const Vec3d& origin) {
  return point_in_world - origin;
}

class FocalSurface {
 public:
  FocalSurface(const FocalSurface&) = default;
  FocalSurface& operator=(const FocalSurface&) = default;
  // The data is shared and never modified, so a move copies the handle: a moved-from surface
  // stays the surface it was (not an empty one whose every accessor would fail).
  FocalSurface(FocalSurface&& other) noexcept : impl_(other.impl_) {}
  FocalSurface& operator=(FocalSurface&& other) noexcept {
    impl_ = other.impl_;
    return *this;
  }

  // A plane in the local frame. Throws for a zero or non-finite normal or point, or a point
  // beyond kMaxSurfaceCoordinate.
  static FocalSurface FromPlane(const Plane& plane);
  // A mesh in world coordinates (Mesh::Check'ed; degenerate triangles dropped and counted).
  static FocalSurface FromMesh(Mesh mesh, std::string source = "");
  // A height field in world coordinates (Heightfield::Check'ed).
  static FocalSurface FromHeightfield(Heightfield heightfield, std::string source = "");
  // A depth map (float32, 1 channel, camera z in metres; not finite or <= 0 = no surface) of the
  // virtual camera `camera` at `cam_from_world` (local frame).
  static FocalSurface FromDepthMap(const Image& depth, const PinholeCamera& camera,
                                   const Rigid3d& cam_from_world);
  // A mesh (a file starting with "ply", or named .obj/.ply) or else any GDAL raster (a DEM).
  static FocalSurface Read(const std::string& path);
  // `surface` (a mesh or height field holding exactly the data of `file`) as Read(file) returns
  // it: file() is `file`. What an unpickled copy of a read surface is (its data travels, and its
  // file's name with it, for the JSON form). Its data is shared, not copied, when `surface` is
  // its only holder.
  static FocalSurface AsReadFrom(FocalSurface surface, const std::string& file);

  FocalSurfaceKind kind() const;
  // The parts of the kind (others are empty / default).
  const Plane& plane() const;
  const Mesh& mesh() const;                // the mesh (for a height field: its triangulation)
  const Heightfield& heightfield() const;  // only for kHeightfield
  const Image& depth() const;              // only for kDepthMap
  const PinholeCamera& depth_camera() const;
  const Rigid3d& depth_cam_from_world() const;
  const std::string& source() const;  // the file it was read from, if any
  // The file Read() read it from, when it is that file's surface as it is (not transformed by
  // InCrs); else empty. What the JSON form carries (focal_surface_json.h).
  const std::string& file() const;
  // One line: "mesh terrain.obj (5837 vertices, 11424 triangles, 0 degenerate dropped)".
  std::string Describe() const;

  // Whether both describe the same surface: same kind and exactly equal data (plane, mesh
  // vertices and triangles, height field, depth map with its camera and pose). Copies share one.
  bool SameAs(const FocalSurface& other) const;

  // The reference point used to resolve up, in the local frame for `origin`.
  Vec3d ReferencePoint(const Vec3d& origin) const;

  // The world x/y box {XMIN, YMIN, XMAX, YMAX} of the surface's vertices for a light field whose
  // origin is `origin` (a depth map's points are local); a plane's is unbounded (+-infinity).
  std::array<double, 4> ExtentInWorld(const Vec3d& origin) const;

  // Depth map (float32, 1 channel, camera.width x camera.height) of the surface placed by
  // `placement`, seen by `camera` at `cam_from_world` (local frame); 0 where a ray misses.
  // num_threads: worker threads of the ray cast, -1 = all cores.
  Image DepthFor(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                 const SurfacePlacement& placement, int num_threads = -1) const;

  // As DepthFor, but every pixel's ray meets the surface moved by its own offset: pixel (x, y)
  // focuses on the surface placed at placement.offset + offsets[y * width + x] along up (a
  // terrain-following stack's fractional slices, merge.h). The ray is cast from the camera
  // centre moved by minus that offset along up onto the unmoved surface: geometrically exact,
  // the hit found in float and its distance recomputed in double, as DepthFor. `offsets` has
  // camera.width * camera.height finite entries (else std::invalid_argument naming `offsets`).
  Image DepthForOffsets(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                        const SurfacePlacement& placement, const std::vector<double>& offsets,
                        int num_threads = -1) const;

  // World z of the (offset) surface under each world (x, y), met by a vertical ray from the up
  // side; NaN where it misses.
  std::vector<double> HeightsAt(const std::vector<Vec2d>& xy_in_world,
                                const SurfacePlacement& placement) const;

  struct Impl;

 private:
  FocalSurface() = default;  // the factories' start: never handed out without impl_
  std::shared_ptr<const Impl> impl_;
};

// The placement of `surface` for a render of `light_field` with the views `view_indices` (empty =
// all): up from the views' mean centre (see above), `offset` along it. Throws
// std::invalid_argument if no selected view has a finite centre.
SurfacePlacement ResolveSurfacePlacement(const FocalSurface& surface, const LightField& light_field,
                                         const std::vector<int>& view_indices, double offset);

// CRSs. A height field carries its raster's CRS; a light field its `crs`. When both are set and
// differ, ResolveSurfacePlacement refuses the surface (its coordinates would be read in the
// wrong frame), and InCrs gives the surface transformed into `crs` through PROJ (every vertex of
// its triangulation: a mesh in the light field's CRS, named "<source> (EPSG:a -> EPSG:b)").
// Without a CRS on either side the coordinates are taken as they are. InCrs returns the surface
// itself when there is nothing to transform. Throws std::invalid_argument naming the file for a
// CRS PROJ cannot transform.
FocalSurface InCrs(const FocalSurface& surface, const std::string& crs);

// The one check of a render on a focal surface that covers none of its pixels (aos-render
// integral and aos.render_integral, planes included; the map: ResolveMapGrid before anything is
// rendered when the surface's x/y box misses the map's, RenderMapTiles after): when
// uncovered_pixels == pixels > 0, throws std::invalid_argument "<source>: no pixel is covered: "
// and, for a surface behind the cameras, SurfaceBehindTheCameras's sentence, else "the surface
// does not cover <what> (or no view sees it); check its extent and CRS"; then the other likely
// causes where they are seen: the
// surface's world x/y box beside `extent_in_world` ({XMIN, YMIN, XMAX, YMAX}; empty = not
// known), a surface with a CRS under a light field without one (its coordinates were taken as
// the light field's world frame), or a surface moved between CRSs. Does nothing otherwise.
void CheckSurfaceCovers(const FocalSurface& surface, const LightField& light_field,
                        const std::string& what, int64_t uncovered_pixels, int64_t pixels,
                        const std::vector<double>& extent_in_world = {});

// Why a render on `surface` could cover nothing because the surface lies behind the cameras
// ("above" them as they look: with z up, every camera looks down and the surface's lowest point
// is higher than the highest camera; mirrored for z down): a sentence naming both z ranges and
// the likely cause (relative altitudes against a terrain's heights), or "" when it does not.
// Planes count when horizontal; depth maps never. CheckSurfaceCovers states it first.
std::string SurfaceBehindTheCameras(const FocalSurface& surface, const LightField& light_field);

// Depth (z in the camera frame, metres) at which each pixel's ray meets `plane`; 0 where the ray
// meets it behind the camera or never (float32, 1 channel). Rows in parallel on num_threads
// (-1 = all cores); the values do not depend on it.
Image PlaneDepth(const PinholeCamera& camera, const Rigid3d& cam_from_world, const Plane& plane,
                 int num_threads = -1);

}  // namespace aos
