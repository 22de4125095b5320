// Bindings of calib/calibrate.h and of the camera files it produces (lightfield/camera_file.h).
// The kwargs merge and the default frame names of aos.calibrate live in python/aos/__init__.py.
#include <filesystem>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <pybind11/stl/filesystem.h>

#include "aos/calib/calibrate.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/camera_file.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

// A frame as given: a file path (read later, without the GIL) or an image copied from an array.
using FrameSource = std::variant<std::string, Image>;

FrameSource FrameFromPython(const py::handle& frame, const std::string& name) {
  const py::module_ os = py::module_::import("os");
  if (py::isinstance<py::str>(frame) || py::isinstance<py::bytes>(frame) ||
      py::isinstance(frame, os.attr("PathLike"))) {
    return py::cast<std::string>(os.attr("fsdecode")(frame));
  }
  return ImageFromArray(frame, /*border=*/0, name);
}

}  // namespace

void BindCalib(py::module_& m) {
  OptionsClass<CalibrateOptions>(
      m, "CalibrateOptions",
      "Options of calibrate (defaults from the C++ struct aos::CalibrateOptions). aos.calibrate "
      "also accepts model as a string ('pinhole', 'radtan', 'fisheye', 'omnidir').")
      .Table()
      .Finish()
      .def("check", &CalibrateOptions::Check, "Raises ValueError naming the field.");

  py::class_<CalibrationResult>(m, "CalibrationResult", "What calibrate returns.")
      .def_readonly("camera", &CalibrationResult::camera,
                    "The calibrated LensCamera (aos pixel convention: cx = OpenCV's cx + 0.5).")
      .def_readonly("rms_px", &CalibrationResult::rms_px,
                    "RMS reprojection error, pixels, as OpenCV reports it.")
      .def_readonly("frames_used", &CalibrationResult::frames_used,
                    "Names of the frames the fit used (omnidir may drop frames its "
                    "initialisation cannot use).")
      .def_readonly("frames_rejected", &CalibrationResult::frames_rejected,
                    "Names of the frames where the board was not found.")
      .def("__repr__", [](const CalibrationResult& result) {
        return std::string("CalibrationResult(model=") + LensModelName(result.camera.model) +
               ", rms_px=" + FormatNumber(result.rms_px) +
               ", frames_used=" + std::to_string(result.frames_used.size()) +
               ", frames_rejected=" + std::to_string(result.frames_rejected.size()) + ")";
      });

  m.def(
      "_calibrate",
      [](const py::sequence& frames, const std::vector<std::string>& names,
         const CalibrateOptions& options, const py::object& progress) {
        if (names.size() != static_cast<size_t>(py::len(frames))) {
          throw py::value_error("names: " + std::to_string(names.size()) + " names for " +
                                std::to_string(py::len(frames)) + " frames");
        }
        std::vector<FrameSource> sources;
        for (size_t i = 0; i < names.size(); ++i) {
          sources.push_back(FrameFromPython(frames[i], names[i]));
        }
        const CalibrateOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          std::vector<Image> images;
          for (FrameSource& source : sources) {
            if (auto* path = std::get_if<std::string>(&source)) {
              images.push_back(ReadImage(*path));
            } else {
              images.push_back(std::move(std::get<Image>(source)));
            }
          }
          return Calibrate(images, names, options_copy, sink);
        });
      },
      "frames"_a, "names"_a, "options"_a, "progress"_a = py::none(),
      "Calibrates a lens from checkerboard frames (numpy arrays, COPIED, or image file paths), "
      "GIL released. Prefer aos.calibrate.");

  m.def(
      "read_camera_file",
      [](const std::filesystem::path& path) {
        py::gil_scoped_release release;
        return ReadCameraFile(path.string());
      },
      "path"_a,
      "Reads a camera file (JSON, format 'aos-camera', as written by `aos-render calibrate` and "
      "write_camera_file) into a LensCamera. Raises ValueError naming the file and the field.");

  m.def(
      "_calibration_record",
      [](const CalibrationResult& result, const std::optional<CalibrateOptions>& options) {
        return CalibrationRecordJson(result, options ? &*options : nullptr);
      },
      "result"_a, "options"_a = py::none(),
      "The calibration record (JSON text) `aos-render calibrate` stores in a camera file.");
  m.def(
      "_write_camera_file",
      [](const std::filesystem::path& path, const LensCamera& camera,
         const std::string& calibration_json) {
        const LensCamera camera_copy = camera;
        py::gil_scoped_release release;
        WriteCameraFile(path.string(), camera_copy, calibration_json);
      },
      "path"_a, "camera"_a, "calibration_json"_a = "",
      "Writes a camera file atomically; calibration_json (a JSON object's text, or '') is stored "
      "as its 'calibration' record. Prefer aos.write_camera_file.");
}

}  // namespace aos::python
