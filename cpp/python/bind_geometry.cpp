// Bindings of geometry/rigid.h, geometry/pinhole.h and geometry/lens.h. Vectors and matrices cross as float64
// numpy arrays by value (see bindings.h).
#include <cmath>
#include <algorithm>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "aos/geometry/heightfield.h"
#include "aos/geometry/lens.h"
#include "aos/geometry/mesh.h"
#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

std::string ReprNumbers(const py::handle& array) {
  return py::str(py::module_::import("numpy").attr("array2string")(array, "separator"_a = ", "));
}

// A number (int or float, numpy scalars included; not bool): a plane may be given as its height.
bool IsRealNumber(const py::handle& value) {
  if (PyBool_Check(value.ptr())) return false;
  return py::isinstance(value, py::module_::import("numbers").attr("Real"));
}

// Plane(point, normal), or Plane(z): the horizontal plane at height z (what a number means
// wherever a plane is taken).
Plane PlaneFromPython(const py::object& point, const std::optional<Vec3d>& normal) {
  if (IsRealNumber(point)) {
    if (normal) {
      throw py::type_error("Plane(z): a height takes no normal (give a point and a normal)");
    }
    return Plane::AtHeight(point.cast<double>());
  }
  Plane plane;
  if (PyBool_Check(point.ptr())) {
    throw py::type_error("Plane: expected a height or a point (3 numbers), got bool");
  }
  if (!point.is_none()) {
    try {
      plane.point = point.cast<Vec3d>();
    } catch (const py::cast_error&) {
      throw py::type_error("Plane: point must be 3 numbers (or the plane a height), got " +
                           std::string(py::repr(point)));
    }
  }
  if (normal) plane.normal = *normal;
  return plane;
}

// Lens distortion in Python has the model's natural length: radtan k1, k2, p1, p2, k3; fisheye
// k1..k4; omnidir k1, k2, p1, p2; pinhole none (C++ keeps 5 numbers, the rest 0).
size_t DistortionLength(LensModel model) {
  return static_cast<size_t>(TraitsOf(model).distortion_count);
}

std::string DistortionNames(LensModel model) {
  const LensModelTraits& traits = TraitsOf(model);
  std::string names;
  for (int i = 0; i < traits.distortion_count; ++i) {
    names += (i == 0 ? "" : ", ") + std::string(traits.distortion_names[static_cast<size_t>(i)]);
  }
  return names.empty() ? "none" : names;
}

std::vector<double> GetDistortion(const LensCamera& lens) {
  const size_t n = DistortionLength(lens.model);
  return std::vector<double>(lens.distortion.begin(), lens.distortion.begin() + n);
}

void SetDistortion(LensCamera& lens, const std::vector<double>& values) {
  const size_t n = DistortionLength(lens.model);
  if (values.size() != n) {
    throw py::value_error("distortion: the " + std::string(LensModelName(lens.model)) +
                          " model takes " + std::to_string(n) + " values (" +
                          DistortionNames(lens.model) + "), got " +
                          std::to_string(values.size()));
  }
  lens.distortion = {0, 0, 0, 0, 0};
  std::copy(values.begin(), values.end(), lens.distortion.begin());
}

std::string ReprNumber(double value) { return FormatNumber(value); }

Rigid3d RigidFromMatrix3x4(const py::array_t<double, py::array::c_style | py::array::forcecast>& m) {
  const bool shape_ok = (m.ndim() == 2 && m.shape(0) == 3 && m.shape(1) == 4) ||
                        (m.ndim() == 1 && m.shape(0) == 12);
  if (!shape_ok) {
    throw py::value_error("from_matrix3x4: expected a 3x4 matrix [R | t] (or 12 numbers, row by "
                          "row)");
  }
  std::array<double, 12> rows{};
  for (int i = 0; i < 12; ++i) rows[i] = m.data()[i];
  return Rigid3d::FromMatrix3x4(rows);
}

}  // namespace

bool LensEqual(const LensCamera& a, const LensCamera& b) {
  return a.SameParameters(b) && a.max_radius == b.max_radius && a.theta_max == b.theta_max;
}

bool PinholeEqual(const PinholeCamera& a, const PinholeCamera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy &&
         a.cx == b.cx && a.cy == b.cy;
}

bool RigidEqual(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation == b.rotation && a.translation == b.translation;
}

// Mesh and Heightfield (geometry/mesh.h, geometry/heightfield.h): arrays cross by copy.
py::array_t<double> MeshVertices(const Mesh& mesh) {
  py::array_t<double> array({static_cast<py::ssize_t>(mesh.vertices.size()), py::ssize_t{3}});
  auto out = array.mutable_unchecked<2>();
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) out(static_cast<py::ssize_t>(i), k) = mesh.vertices[i][k];
  }
  return array;
}

py::array_t<int32_t> MeshTriangles(const Mesh& mesh) {
  py::array_t<int32_t> array({static_cast<py::ssize_t>(mesh.triangles.size()), py::ssize_t{3}});
  auto out = array.mutable_unchecked<2>();
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) out(static_cast<py::ssize_t>(i), k) = mesh.triangles[i][k];
  }
  return array;
}

Mesh MeshFromArrays(const py::handle& vertices_object, const py::handle& triangles_object,
                    int64_t dropped) {
  const auto vertices = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(vertices_object);
  const auto triangles = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(triangles_object);
  if (!vertices || vertices.ndim() != 2 || vertices.shape(1) != 3) {
    throw py::value_error("Mesh: vertices must be an (N, 3) array of numbers");
  }
  if (!triangles || triangles.ndim() != 2 || triangles.shape(1) != 3) {
    throw py::value_error("Mesh: triangles must be an (M, 3) array of integers");
  }
  Mesh mesh;
  auto v = vertices.unchecked<2>();
  for (py::ssize_t i = 0; i < v.shape(0); ++i) mesh.vertices.emplace_back(v(i, 0), v(i, 1), v(i, 2));
  auto t = triangles.unchecked<2>();
  for (py::ssize_t i = 0; i < t.shape(0); ++i) {
    std::array<int, 3> triangle{};
    for (int k = 0; k < 3; ++k) {
      if (t(i, k) < 0 || t(i, k) >= static_cast<int64_t>(mesh.vertices.size())) {
        throw py::value_error("Mesh: triangle " + std::to_string(i) + ": vertex index " +
                              std::to_string(t(i, k)) + " is out of range (" +
                              std::to_string(mesh.vertices.size()) + " vertices)");
      }
      triangle[static_cast<size_t>(k)] = static_cast<int>(t(i, k));
    }
    mesh.triangles.push_back(triangle);
  }
  mesh.dropped_triangles = dropped;
  DropDegenerateTriangles(mesh);
  mesh.Check("Mesh");
  return mesh;
}

py::array_t<float> HeightArray(const Heightfield& field) {
  py::array_t<float> array({static_cast<py::ssize_t>(field.height), static_cast<py::ssize_t>(field.width)});
  std::copy(field.heights.begin(), field.heights.end(), array.mutable_data());
  return array;
}

Heightfield HeightfieldFromArrays(const py::handle& heights_object, const std::array<double, 6>& geotransform,
                                  const std::string& crs) {
  const auto heights = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(heights_object);
  if (!heights || heights.ndim() != 2) throw py::value_error("Heightfield: heights must be an (H, W) array");
  Heightfield field;
  field.height = static_cast<int>(heights.shape(0));
  field.width = static_cast<int>(heights.shape(1));
  field.geotransform = geotransform;
  field.crs_wkt = crs;
  field.heights.assign(heights.data(), heights.data() + heights.size());
  field.Check("Heightfield");
  return field;
}

void BindTerrain(py::module_& m) {
  py::class_<Mesh>(m, "Mesh",
                   "A triangle mesh in WORLD coordinates (light field origin + local), e.g. a "
                   "terrain (DEM) for a focal surface. Arrays are copies.")
      .def(py::init([](const py::object& vertices, const py::object& triangles) {
             return MeshFromArrays(vertices, triangles, 0);
           }),
           "vertices"_a, "triangles"_a,
           "From (N, 3) vertices and (M, 3) 0-based triangle indices; degenerate triangles are "
           "dropped and counted in dropped_triangles. Raises ValueError for non-finite vertices, "
           "indices out of range, or no triangle.")
      .def_static("read", &ReadMesh, "path"_a,
                  "Reads an OBJ or PLY (ascii or binary_little_endian) mesh; degenerate "
                  "triangles are dropped and counted. Raises ValueError naming the file, line or "
                  "element and field.")
      .def_property_readonly("vertices", &MeshVertices, "float64 (N, 3), world metres (a copy).")
      .def_property_readonly("triangles", &MeshTriangles, "int32 (M, 3) vertex indices (a copy).")
      .def_readonly("dropped_triangles", &Mesh::dropped_triangles,
                    "Degenerate triangles (repeated index or zero area) dropped on reading.")
      .def("__eq__",
           [](const Mesh& a, const py::object& other) -> py::object {
             if (!py::isinstance<Mesh>(other)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
             const Mesh& b = other.cast<const Mesh&>();
             return py::bool_(a.vertices == b.vertices && a.triangles == b.triangles &&
                              a.dropped_triangles == b.dropped_triangles);
           },
           "other"_a)
      .def(py::pickle(
          [](const Mesh& mesh) {
            return py::dict("vertices"_a = MeshVertices(mesh), "triangles"_a = MeshTriangles(mesh),
                            "dropped_triangles"_a = mesh.dropped_triangles);
          },
          [](const py::object& state) {
            const py::dict values = StateDict(state, "Mesh", {"vertices", "triangles", "dropped_triangles"});
            return MeshFromArrays(values["vertices"], values["triangles"],
                                  values["dropped_triangles"].cast<int64_t>());
          }))
      .def("__repr__", [](const Mesh& mesh) {
        return "Mesh(" + std::to_string(mesh.vertices.size()) + " vertices, " +
               std::to_string(mesh.triangles.size()) + " triangles, dropped_triangles=" +
               std::to_string(mesh.dropped_triangles) + ")";
      });

  py::class_<Heightfield>(m, "Heightfield",
                          "A DEM raster: heights (H, W) at the pixel centres the geotransform "
                          "places in WORLD coordinates (x = gt[0] + (i + 0.5) gt[1], y = gt[3] + "
                          "(j + 0.5) gt[5]); NaN = nodata.")
      .def(py::init(&HeightfieldFromArrays), "heights"_a, "geotransform"_a, "crs"_a = "",
           "From float32 heights (H, W) (copied; NaN = nodata), a north-up GDAL geotransform "
           "(6 numbers) and a CRS as WKT (or empty).")
      .def_static("read", &ReadHeightfield, "path"_a,
                  "Reads band 1 of a GDAL raster (GeoTIFF, ...): nodata becomes NaN. Raises "
                  "ValueError for rotated geotransforms, absurd sizes, all-nodata rasters.")
      .def("write", [](const Heightfield& field, const std::string& path, bool overwrite) {
             WriteHeightfield(path, field, overwrite);
           },
           "path"_a, "overwrite"_a = false,
           "Writes a float32 GeoTIFF (nodata NaN), atomically; refuses an existing file unless "
           "overwrite, and a path not ending in .tif or .tiff.")
      .def("to_mesh", [](const Heightfield& field) { return HeightfieldToMesh(field); },
           "Two triangles per cell of 2 x 2 valid pixel centres (world coordinates).")
      .def_readonly("width", &Heightfield::width, "Pixels.")
      .def_readonly("height", &Heightfield::height, "Pixels.")
      .def_property_readonly("heights", &HeightArray, "float32 (H, W), metres, NaN = nodata (a copy).")
      .def_property_readonly(
          "geotransform",
          [](const Heightfield& field) {
            const auto& g = field.geotransform;
            return py::make_tuple(g[0], g[1], g[2], g[3], g[4], g[5]);
          },
          "GDAL geotransform (6 numbers, a tuple).")
      .def_readonly("crs", &Heightfield::crs_wkt, "The CRS as WKT; empty when the raster has none.")
      .def_readonly("source", &Heightfield::source,
                    "The file it was read from (messages name it); '' when built from arrays.")
      .def("__eq__",
           [](const Heightfield& a, const py::object& other) -> py::object {
             if (!py::isinstance<Heightfield>(other)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
             const Heightfield& b = other.cast<const Heightfield&>();
             bool same = a.width == b.width && a.height == b.height && a.geotransform == b.geotransform &&
                         a.crs_wkt == b.crs_wkt && a.heights.size() == b.heights.size();
             for (size_t i = 0; same && i < a.heights.size(); ++i) {
               same = a.heights[i] == b.heights[i] || (std::isnan(a.heights[i]) && std::isnan(b.heights[i]));
             }
             return py::bool_(same);
           },
           "other"_a, "Exact equality (NaN equals NaN).")
      .def(py::pickle(
          [](const Heightfield& field) {
            return py::dict("heights"_a = HeightArray(field), "geotransform"_a = field.geotransform,
                            "crs"_a = field.crs_wkt, "source"_a = field.source);
          },
          [](const py::object& state) {
            const py::dict values =
                StateDict(state, "Heightfield", {"heights", "geotransform", "crs", "source"});
            Heightfield field = HeightfieldFromArrays(
                values["heights"], values["geotransform"].cast<std::array<double, 6>>(),
                values["crs"].cast<std::string>());
            field.source = values["source"].cast<std::string>();
            return field;
          }))
      .def("__repr__", [](const Heightfield& field) {
        return "Heightfield(" + std::to_string(field.width) + "x" + std::to_string(field.height) +
               ", pixel " + FormatNumber(field.geotransform[1]) + " x " +
               FormatNumber(field.geotransform[5]) + ", crs=" +
               (field.crs_wkt.empty() ? std::string("none") : std::string("set")) + ")";
      });
}

void BindGeometry(py::module_& m) {
  py::class_<Rigid3d>(m, "Rigid3d",
                      "A rigid transform x_b = rotation @ x_a + translation, named b_from_a where "
                      "used (cam_from_world maps world points to OpenCV camera axes: x right, y "
                      "down, z forward). Properties return new float64 arrays (copies).")
      .def(py::init([](const Mat3d& rotation, const Vec3d& translation) {
             return Rigid3d{rotation, translation};
           }),
           "rotation"_a = Rigid3d{}.rotation, "translation"_a = Rigid3d{}.translation,
           "From a 3x3 rotation and a 3-vector translation (any array-like). Not validated here; "
           "views check their pose when added.")
      .def_readwrite("rotation", &Rigid3d::rotation, "3x3 rotation matrix (float64 copy).")
      .def_readwrite("translation", &Rigid3d::translation, "Translation 3-vector (float64 copy).")
      .def_property_readonly("center", &Rigid3d::Center,
                             "For cam_from_world: the camera centre in world coordinates, -R^T t.")
      .def("inverse", &Rigid3d::Inverse, "The inverse transform (a_from_b for b_from_a).")
      .def_property_readonly(
          "matrix3x4",
          [](const Rigid3d& transform) {
            const auto rows = transform.ToMatrix3x4();
            py::array_t<double> array({3, 4});
            std::copy(rows.begin(), rows.end(), array.mutable_data());
            return array;
          },
          "The 3x4 matrix [R | t] (float64 copy).")
      .def_static("from_matrix3x4", &RigidFromMatrix3x4, "m"_a,
                  "From the 3x4 matrix [R | t] (array-like of shape (3, 4), or 12 numbers row by "
                  "row).")
      .def(
          "__eq__",
          [](const Rigid3d& a, const py::object& other) -> py::object {
            if (!py::isinstance<Rigid3d>(other)) {
              return py::reinterpret_borrow<py::object>(Py_NotImplemented);
            }
            return py::bool_(RigidEqual(a, other.cast<const Rigid3d&>()));
          },
          "other"_a, "Exact equality of rotation and translation.")
      .def(py::pickle(
          [](const Rigid3d& transform) {
            return py::dict("rotation"_a = transform.rotation,
                            "translation"_a = transform.translation);
          },
          [](const py::object& state) {
            const py::dict values = StateDict(state, "Rigid3d", {"rotation", "translation"});
            return Rigid3d{values["rotation"].cast<Mat3d>(), values["translation"].cast<Vec3d>()};
          }))
      .def("__repr__", [](const Rigid3d& transform) {
        std::ostringstream stream;
        stream << transform;
        return stream.str();
      });

  m.def(
      "look_at",
      [](const Vec3d& eye, const Vec3d& target, const std::optional<Vec3d>& up) {
        return up ? LookAt(eye, target, *up) : LookAt(eye, target);
      },
      "eye"_a, "target"_a, "up"_a = py::none(),
      "cam_from_world of a camera at `eye` looking at `target`; `up` is the world direction "
      "that appears up in the image (image y points down); None = +z, or +y for a camera "
      "looking straight along z (a nadir view). Raises ValueError if eye == target or up is "
      "parallel to the viewing direction.");

  py::class_<Plane>(m, "Plane",
                    "A plane through `point` with normal `normal` (any length > 0; the side does "
                    "not matter). Local frame, metres.")
      .def(py::init(&PlaneFromPython), "point"_a = Plane{}.point, "normal"_a = py::none(),
           "A plane through `point` with `normal` (default (0, 0, 1)); Plane(z) with a number "
           "is the horizontal plane at height z, as Plane.at_height(z). Numbers are accepted as "
           "planes wherever a Plane is taken.")
      .def_readwrite("point", &Plane::point, "A point on the plane (float64 copy).")
      .def_readwrite("normal", &Plane::normal, "The plane normal (float64 copy).")
      .def_static("at_height", &Plane::AtHeight, "z"_a, "The horizontal plane at height z.")
      .def_static("in_front_of", &Plane::InFrontOf, "cam_from_world"_a, "distance"_a,
                  "horizontal"_a = false,
                  "The plane `distance` metres in front of a camera along its axis: "
                  "perpendicular to the axis, or horizontal through that point.")
      .def(
          "__eq__",
          [](const Plane& a, const py::object& other) -> py::object {
            if (!py::isinstance<Plane>(other)) {
              return py::reinterpret_borrow<py::object>(Py_NotImplemented);
            }
            const Plane& b = other.cast<const Plane&>();
            return py::bool_(a.point == b.point && a.normal == b.normal);
          },
          "other"_a, "Exact equality of point and normal (not of the planes as sets).")
      .def(py::pickle(
          [](const Plane& plane) {
            return py::dict("point"_a = plane.point, "normal"_a = plane.normal);
          },
          [](const py::object& state) {
            const py::dict values = StateDict(state, "Plane", {"point", "normal"});
            return Plane{values["point"].cast<Vec3d>(), values["normal"].cast<Vec3d>()};
          }))
      .def("__repr__", [](const Plane& plane) {
        py::object point = py::cast(plane.point);
        py::object normal = py::cast(plane.normal);
        return "Plane(point=" + ReprNumbers(point) + ", normal=" + ReprNumbers(normal) + ")";
      });

  // A number wherever a Plane is taken (options fields, function arguments) is the horizontal
  // plane at that height: the conversion calls Plane(z) above (bool is refused there).
  py::implicitly_convertible<double, Plane>();
  py::implicitly_convertible<int, Plane>();

  py::class_<PinholeCamera>(
      m, "PinholeCamera",
      "A pinhole camera. Pixel convention: continuous coordinates (u, v) from the top-left image "
      "corner, u right, v down; pixel (i, j) covers [i, i+1) x [j, j+1), its centre is at "
      "(i + 0.5, j + 0.5). Projection of camera point (x, y, z): u = fx x / z + cx, "
      "v = fy y / z + cy (z > 0).")
      .def(py::init([](int width, int height, double fx, double fy, double cx, double cy) {
             return PinholeCamera{width, height, fx, fy, cx, cy};
           }),
           "width"_a, "height"_a, "fx"_a, "fy"_a, "cx"_a, "cy"_a)
      .def_readwrite("width", &PinholeCamera::width, "Image width, pixels (> 0).")
      .def_readwrite("height", &PinholeCamera::height, "Image height, pixels (> 0).")
      .def_readwrite("fx", &PinholeCamera::fx, "Focal length in pixels along u (> 0).")
      .def_readwrite("fy", &PinholeCamera::fy, "Focal length in pixels along v (> 0).")
      .def_readwrite("cx", &PinholeCamera::cx, "Principal point u, pixels (continuous).")
      .def_readwrite("cy", &PinholeCamera::cy, "Principal point v, pixels (continuous).")
      .def_static("from_fov", &PinholeCamera::FromFov, "width"_a, "height"_a, "fov_deg"_a,
                  "Square pixels, principal point at the image centre, fov_deg the full "
                  "horizontal field of view (0 < fov_deg < 180). Raises ValueError otherwise.")
      .def_property_readonly("K", &PinholeCamera::K,
                             "The 3x3 intrinsic matrix (float64 copy).")
      .def("fov_x_deg", &PinholeCamera::FovXDeg, "Horizontal field of view, degrees.")
      .def("project", &PinholeCamera::Project, "point"_a,
           "Continuous pixel coordinates (u, v) of a point in camera coordinates (defined for "
           "z > 0 only).")
      .def("unproject", &PinholeCamera::Unproject, "pixel"_a,
           "The ray direction (z = 1) through continuous pixel coordinates (u, v).")
      .def("check", &PinholeCamera::Check, "where"_a = "camera",
           "Raises ValueError naming `where` if a field is out of range or not finite.")
      .def(
          "__eq__",
          [](const PinholeCamera& a, const py::object& other) -> py::object {
            if (!py::isinstance<PinholeCamera>(other)) {
              return py::reinterpret_borrow<py::object>(Py_NotImplemented);
            }
            return py::bool_(PinholeEqual(a, other.cast<const PinholeCamera&>()));
          },
          "other"_a, "Exact equality of every field.")
      .def(py::pickle(
          [](const PinholeCamera& c) {
            return py::dict("width"_a = c.width, "height"_a = c.height, "fx"_a = c.fx,
                            "fy"_a = c.fy, "cx"_a = c.cx, "cy"_a = c.cy);
          },
          [](const py::object& state) {
            const py::dict v =
                StateDict(state, "PinholeCamera", {"width", "height", "fx", "fy", "cx", "cy"});
            return PinholeCamera{v["width"].cast<int>(), v["height"].cast<int>(),
                                 v["fx"].cast<double>(), v["fy"].cast<double>(),
                                 v["cx"].cast<double>(), v["cy"].cast<double>()};
          }))
      .def("__repr__", [](const PinholeCamera& camera) {
        return "PinholeCamera(width=" + std::to_string(camera.width) +
               ", height=" + std::to_string(camera.height) + ", fx=" + FormatNumber(camera.fx) +
               ", fy=" + FormatNumber(camera.fy) + ", cx=" + FormatNumber(camera.cx) +
               ", cy=" + FormatNumber(camera.cy) + ")";
      });

  BindEnum<LensModel>(m, "LensModel", "Lens model of a LensCamera (aos/geometry/lens.h).");

  py::class_<LensCamera>(
      m, "LensCamera",
      "A camera with a lens model: pinhole, OpenCV radial-tangential (distortion k1, k2, p1, p2, "
      "k3), OpenCV fisheye (k1..k4, 0) or OpenCV omnidirectional (Mei: xi, skew, k1, k2, p1, "
      "p2, 0). Pixel centres at +0.5 (OpenCV's cx = cx - 0.5). Call finalize() after changing "
      "fields. `distortion` has the model's natural length: radtan 5 (k1, k2, p1, p2, k3), "
      "fisheye 4 (k1..k4), omnidir 4 (k1, k2, p1, p2), pinhole 0.")
      .def(py::init([](LensModel model, int width, int height, double fx, double fy, double cx,
                       double cy, const std::optional<std::vector<double>>& distortion,
                       double xi, double skew) {
             LensCamera lens;
             lens.model = model;
             lens.width = width;
             lens.height = height;
             lens.fx = fx;
             lens.fy = fy;
             lens.cx = cx;
             lens.cy = cy;
             if (distortion) SetDistortion(lens, *distortion);
             lens.xi = xi;
             lens.skew = skew;
             lens.Finalize("camera");
             return lens;
           }),
           "model"_a, "width"_a, "height"_a, "fx"_a, "fy"_a, "cx"_a, "cy"_a,
           "distortion"_a = py::none(), "xi"_a = 0.0, "skew"_a = 0.0,
           "Raises ValueError for parameters that are not invertible (xi < 0, a radtan "
           "distortion folding inside the frame) and for a distortion list whose length is not "
           "the model's (None: no distortion).")
      .def_static("from_pinhole", &LensCamera::FromPinhole, "camera"_a)
      .def("pinhole", &LensCamera::Pinhole,
           "The pinhole part as a PinholeCamera (size, fx, fy, cx, cy; for a lens model its "
           "distortion, skew and xi are dropped).")
      .def_readwrite("model", &LensCamera::model)
      .def_readwrite("width", &LensCamera::width)
      .def_readwrite("height", &LensCamera::height)
      .def_readwrite("fx", &LensCamera::fx)
      .def_readwrite("fy", &LensCamera::fy)
      .def_readwrite("cx", &LensCamera::cx)
      .def_readwrite("cy", &LensCamera::cy)
      .def_readwrite("skew", &LensCamera::skew)
      .def_readwrite("xi", &LensCamera::xi)
      .def_property("distortion", &GetDistortion, &SetDistortion,
                    "The model's distortion coefficients, a new list of its natural length: "
                    "radtan k1, k2, p1, p2, k3; fisheye k1..k4; omnidir k1, k2, p1, p2; pinhole "
                    "none. Setting another length raises ValueError naming the model (set model "
                    "first).")
      .def_readonly("max_radius", &LensCamera::max_radius,
                    "Largest valid undistorted normalised radius (radtan, omnidir).")
      .def_readonly("theta_max", &LensCamera::theta_max,
                    "Largest valid ray angle from the axis, radians.")
      .def("finalize", &LensCamera::Finalize, "where"_a = "camera",
           "Validates the parameters and computes the valid field.")
      .def(
          "project",
          [](const LensCamera& lens, const Vec3d& point) -> std::optional<Vec2d> {
            Vec2d pixel;
            if (!lens.Project(point, &pixel)) return std::nullopt;
            return pixel;
          },
          "point"_a, "Pixel (u, v) of a point in the camera frame, or None outside the valid field.")
      .def(
          "unproject",
          [](const LensCamera& lens, const Vec2d& pixel) -> std::optional<Vec3d> {
            Vec3d ray;
            if (!lens.Unproject(pixel, &ray)) return std::nullopt;
            return ray;
          },
          "pixel"_a, "Unit ray through the pixel, or None where no valid ray maps there.")
      .def(
          "unproject_pixels",
          [](const LensCamera& lens, const py::array_t<double, py::array::c_style | py::array::forcecast>& pixels) {
            if (pixels.ndim() != 2 || pixels.shape(1) != 2) {
              throw py::value_error("unproject_pixels: pixels must have shape (N, 2)");
            }
            const ssize_t n = pixels.shape(0);
            py::array_t<double> rays({n, static_cast<ssize_t>(3)});
            auto in = pixels.unchecked<2>();
            auto out = rays.mutable_unchecked<2>();
            {
              py::gil_scoped_release release;
              for (ssize_t i = 0; i < n; ++i) {
                Vec3d ray;
                if (!lens.Unproject(Vec2d(in(i, 0), in(i, 1)), &ray)) {
                  ray = Vec3d(std::nan(""));
                }
                for (int k = 0; k < 3; ++k) out(i, k) = ray[k];
              }
            }
            return rays;
          },
          "pixels"_a,
          "Unit rays (N, 3) through pixels (N, 2), float64 (a new array); NaN rows where no "
          "valid ray maps there.")
      .def(
          "__eq__",
          [](const LensCamera& a, const py::object& other) -> py::object {
            if (!py::isinstance<LensCamera>(other)) {
              return py::reinterpret_borrow<py::object>(Py_NotImplemented);
            }
            return py::bool_(LensEqual(a, other.cast<const LensCamera&>()));
          },
          "other"_a, "Exact equality of every field.")
      .def(py::pickle(
          [](const LensCamera& c) {
            // All five stored coefficients and the derived valid field: the copy is exact.
            return py::dict("model"_a = c.model, "width"_a = c.width, "height"_a = c.height,
                            "fx"_a = c.fx, "fy"_a = c.fy, "cx"_a = c.cx, "cy"_a = c.cy,
                            "skew"_a = c.skew, "xi"_a = c.xi, "coefficients"_a = c.distortion,
                            "max_radius"_a = c.max_radius, "theta_max"_a = c.theta_max);
          },
          [](const py::object& state) {
            const py::dict v = StateDict(state, "LensCamera",
                                         {"model", "width", "height", "fx", "fy", "cx", "cy",
                                          "skew", "xi", "coefficients", "max_radius",
                                          "theta_max"});
            LensCamera c;
            c.model = v["model"].cast<LensModel>();
            c.width = v["width"].cast<int>();
            c.height = v["height"].cast<int>();
            c.fx = v["fx"].cast<double>();
            c.fy = v["fy"].cast<double>();
            c.cx = v["cx"].cast<double>();
            c.cy = v["cy"].cast<double>();
            c.skew = v["skew"].cast<double>();
            c.xi = v["xi"].cast<double>();
            c.distortion = v["coefficients"].cast<std::array<double, 5>>();
            c.max_radius = v["max_radius"].cast<double>();
            c.theta_max = v["theta_max"].cast<double>();
            return c;
          }))
      .def("__repr__", [](const LensCamera& c) {
        std::string distortion;
        for (double value : GetDistortion(c)) {
          distortion += (distortion.empty() ? "" : ", ") + ReprNumber(value);
        }
        std::string text = std::string("LensCamera(model=") + LensModelName(c.model) +
                           ", width=" + std::to_string(c.width) +
                           ", height=" + std::to_string(c.height) + ", fx=" + ReprNumber(c.fx) +
                           ", fy=" + ReprNumber(c.fy) + ", cx=" + ReprNumber(c.cx) +
                           ", cy=" + ReprNumber(c.cy) + ", distortion=[" + distortion + "]";
        if (c.traits().has_xi) {
          text += ", xi=" + ReprNumber(c.xi) + ", skew=" + ReprNumber(c.skew);
        }
        return text + ")";
      });
  BindTerrain(m);
}

}  // namespace aos::python
