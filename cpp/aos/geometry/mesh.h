#pragma once
// Triangle meshes read from OBJ and PLY files: the terrain meshes (DEMs) that focal surfaces are
// made of (render/focal_surface.h).
//
// Contract
// - Vertices are in WORLD coordinates as the file gives them (metres; for a light field,
//   world = LightField::origin + local). They are kept in double precision; whoever ray casts
//   them moves them near the data first (focal_surface.h).
// - OBJ: `v x y z [w]` lines (w ignored) and `f` lines whose corners are `v`, `v/vt`, `v/vt/vn`
//   or `v//vn` with 1-based indices, negative ones counting back from the last vertex read so
//   far (a face may use only vertices defined before it, as writers do); polygons with more than three corners are fan-triangulated (0,1,2), (0,2,3), ...
//   Every other line (vt, vn, o, g, s, usemtl, mtllib, comments) is ignored.
// - PLY: `format ascii 1.0` or `format binary_little_endian 1.0`; element `vertex` with float or
//   double (any PLY scalar type) properties x, y, z (other properties skipped); element `face`
//   with a list property `vertex_indices` (or `vertex_index`), polygons fan-triangulated as for
//   OBJ; other elements skipped.
// - Degenerate triangles (a repeated vertex index, or zero area in double precision: the cross
//   product of two edges is exactly zero) are dropped, not an error, and counted in
//   Mesh::dropped_triangles.
//
// - Coordinates. Every vertex coordinate is finite and |x|, |y|, |z| <= kMaxSurfaceCoordinate
//   (1e9 m), else the vertex is refused. 1e9 m is more than any terrestrial CRS holds (the
//   equator is 4.0e7 m = 1.3e8 US ft long; geocentric coordinates reach 6.4e6 m), so only a
//   broken file (an undeclared nodata value such as -3.4e38, a unit mistake) is refused. It also
//   keeps the surface inside what the float ray cast can hold (focal_surface.h,
//   kMaxRayCastRadius): Embree asserts on ray origins beyond 1.8e18 (its FLT_LARGE) and its
//   triangle test forms products of three coordinates (1e9^3 = 1e27, far below FLT_MAX 3.4e38).
// - Sizes. The counts a PLY header declares are checked before anything is allocated: against
//   the file (every element takes at least one byte per property: binary, the sum of its
//   properties' sizes; ASCII, one character and a separator each) and against the memory budget
//   (util/memory.h, AOS_MEMORY_LIMIT_MB); an OBJ's vertices and triangles are counted in a first
//   pass and checked against the budget the same way. Either refusal is one std::invalid_argument
//   naming the file and the header element, never std::bad_alloc.
//
// Throws std::invalid_argument naming the file, the line (OBJ) or element (PLY) and the field for
// a file that cannot be read, a non-finite or out-of-range vertex coordinate, a face index out of
// range, a face with fewer than 3 corners, an unknown PLY format or property type, a truncated
// file, header counts the file cannot hold or the memory budget cannot take, and a mesh with no
// vertex or no (non-degenerate) triangle.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "aos/geometry/rigid.h"

namespace aos {

// The largest |coordinate| of a surface's vertex (or height, or pixel centre), metres. See the
// contract above.
inline constexpr double kMaxSurfaceCoordinate = 1e9;

// Empty when |value| <= kMaxSurfaceCoordinate (and finite), else the reason:
// "is not finite (nan)" / "is 1e+20 m, beyond +-1e9 m (the most a surface coordinate may be)".
std::string SurfaceCoordinateProblem(double value);

struct Mesh {
  std::vector<Vec3d> vertices;                // world coordinates, metres
  std::vector<std::array<int, 3>> triangles;  // 0-based indices into vertices
  // Degenerate triangles (repeated index or zero area) dropped by ReadMesh (or
  // DropDegenerateTriangles); they are not in `triangles`.
  int64_t dropped_triangles = 0;

  // Throws std::invalid_argument ("<where>: ...") for no vertices, no triangles, a non-finite
  // vertex or one beyond kMaxSurfaceCoordinate, or an index out of range.
  void Check(const std::string& where) const;
};

// Reads an OBJ (.obj) or PLY (.ply) mesh; the format is chosen by the file's first bytes ("ply"
// starts a PLY file), else the extension. See the contract above.
Mesh ReadMesh(const std::string& path);

// The vertices of an OBJ or PLY file, faces not required: a point cloud (e.g. the sparse points
// `aos-render poses --points-output` writes). Throws as ReadMesh, for no vertex or a non-finite
// one, but not for missing faces.
std::vector<Vec3d> ReadPoints(const std::string& path);

// Writes vertices (double x, y, z) and triangles (if any) as a binary little-endian PLY that
// ReadMesh / ReadPoints read back exactly, under a temporary name renamed into place. Refuses an
// existing file unless `overwrite`. Throws std::invalid_argument naming the file.
void WritePly(const std::string& path, const std::vector<Vec3d>& vertices,
              const std::vector<std::array<int, 3>>& triangles = {}, bool overwrite = false);

// Whether `path` names a mesh file ReadMesh reads: its first bytes are "ply", or its name ends
// in .obj or .ply (any case). Throws std::invalid_argument naming the file if it cannot be opened.
bool IsMeshFile(const std::string& path);

// Removes degenerate triangles from `mesh`, adding their number to mesh.dropped_triangles.
void DropDegenerateTriangles(Mesh& mesh);

}  // namespace aos
