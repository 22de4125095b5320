// Bindings of geometry/rigid.h, geometry/pinhole.h and geometry/lens.h. Vectors and matrices cross as float64
// numpy arrays by value (see bindings.h).
#include <cmath>
#include <optional>
#include <sstream>

#include "aos/geometry/lens.h"
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
      .def(py::init([](const Vec3d& point, const Vec3d& normal) { return Plane{point, normal}; }),
           "point"_a = Plane{}.point, "normal"_a = Plane{}.normal)
      .def_readwrite("point", &Plane::point, "A point on the plane (float64 copy).")
      .def_readwrite("normal", &Plane::normal, "The plane normal (float64 copy).")
      .def_static("at_height", &Plane::AtHeight, "z"_a, "The horizontal plane at height z.")
      .def_static("in_front_of", &Plane::InFrontOf, "cam_from_world"_a, "distance"_a,
                  "horizontal"_a = false,
                  "The plane `distance` metres in front of a camera along its axis: "
                  "perpendicular to the axis, or horizontal through that point.")
      .def("__repr__", [](const Plane& plane) {
        py::object point = py::cast(plane.point);
        py::object normal = py::cast(plane.normal);
        return "Plane(point=" + ReprNumbers(point) + ", normal=" + ReprNumbers(normal) + ")";
      });

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
      .def("__repr__", [](const PinholeCamera& camera) {
        return "PinholeCamera(width=" + std::to_string(camera.width) +
               ", height=" + std::to_string(camera.height) + ", fx=" + FormatNumber(camera.fx) +
               ", fy=" + FormatNumber(camera.fy) + ", cx=" + FormatNumber(camera.cx) +
               ", cy=" + FormatNumber(camera.cy) + ")";
      });

  py::enum_<LensModel>(m, "LensModel", "Lens model of a LensCamera (aos/geometry/lens.h).")
      .value("pinhole", LensModel::kPinhole)
      .value("radtan", LensModel::kRadTan)
      .value("fisheye", LensModel::kFisheye)
      .value("omnidir", LensModel::kOmnidir);

  py::class_<LensCamera>(
      m, "LensCamera",
      "A camera with a lens model: pinhole, OpenCV radial-tangential (distortion k1, k2, p1, p2, "
      "k3), OpenCV fisheye (k1..k4, 0) or OpenCV omnidirectional (Mei: xi, skew, k1, k2, p1, "
      "p2, 0). Pixel centres at +0.5 (OpenCV's cx = cx - 0.5). Call finalize() after changing "
      "fields.")
      .def(py::init([](LensModel model, int width, int height, double fx, double fy, double cx,
                       double cy, const std::array<double, 5>& distortion, double xi,
                       double skew) {
             LensCamera lens;
             lens.model = model;
             lens.width = width;
             lens.height = height;
             lens.fx = fx;
             lens.fy = fy;
             lens.cx = cx;
             lens.cy = cy;
             lens.distortion = distortion;
             lens.xi = xi;
             lens.skew = skew;
             lens.Finalize("camera");
             return lens;
           }),
           "model"_a, "width"_a, "height"_a, "fx"_a, "fy"_a, "cx"_a, "cy"_a,
           "distortion"_a = std::array<double, 5>{0, 0, 0, 0, 0}, "xi"_a = 0.0, "skew"_a = 0.0,
           "Raises ValueError for parameters that are not invertible (xi < 0, a radtan "
           "distortion folding inside the frame).")
      .def_static("from_pinhole", &LensCamera::FromPinhole, "camera"_a)
      .def_readwrite("model", &LensCamera::model)
      .def_readwrite("width", &LensCamera::width)
      .def_readwrite("height", &LensCamera::height)
      .def_readwrite("fx", &LensCamera::fx)
      .def_readwrite("fy", &LensCamera::fy)
      .def_readwrite("cx", &LensCamera::cx)
      .def_readwrite("cy", &LensCamera::cy)
      .def_readwrite("skew", &LensCamera::skew)
      .def_readwrite("xi", &LensCamera::xi)
      .def_readwrite("distortion", &LensCamera::distortion)
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
          "valid ray maps there.");
}

}  // namespace aos::python
