// Bindings of metrics/quality.h. Images are numpy arrays (copied, see bindings.h); the options
// are the C++ QualityOptions, so names and defaults match the CLI's `metrics` subcommand.
#include <optional>

#include "aos/metrics/quality.h"
#include "aos/metrics/resolution.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {

using namespace pybind11::literals;

void BindMetrics(py::module_& m) {
  OptionsClass<QualityOptions>(
      m, "QualityOptions",
      "Options of compare_images (defaults from the C++ struct aos::QualityOptions).")
      .Table()
      .Finish()
      .def("check", &QualityOptions::Check, "Raises ValueError naming the offending field.");

  py::class_<QualityResult>(m, "QualityResult", "Result of compare_images (see docs/metrics.md).")
      .def_readonly("mse", &QualityResult::mse, "Mean squared error over channels and pixels.")
      .def_readonly("psnr_db", &QualityResult::psnr_db, "10 log10(L^2 / MSE); inf if identical.")
      .def_readonly("ssim", &QualityResult::ssim, "SSIM, mean over channels.")
      .def_readonly("ssim_channels", &QualityResult::ssim_channels, "SSIM per channel.")
      .def_readonly("color_ssim", &QualityResult::color_ssim,
                    "Quaternion colour SSIM (equals ssim for one channel).")
      .def_readonly("data_range", &QualityResult::data_range, "The L used.")
      .def_readonly("mse_pixels", &QualityResult::mse_pixels, "Pixels in MSE/PSNR.")
      .def_readonly("ssim_pixels", &QualityResult::ssim_pixels, "Pixels in the SSIM averages.")
      .def_readonly("test_scale", &QualityResult::test_scale,
                    "Factor applied to the test image (integer images of different types).")
      .def_readonly("note", &QualityResult::note,
                    "How mismatched sample types were reconciled; empty when the types agree.")
      .def("__repr__", [](const QualityResult& r) {
        return "QualityResult(psnr_db=" + std::to_string(r.psnr_db) + ", ssim=" +
               std::to_string(r.ssim) + ", color_ssim=" + std::to_string(r.color_ssim) + ")";
      });

  m.def(
      "_compare_images",
      [](const py::handle& test, const py::handle& reference, const py::object& mask,
         const QualityOptions& options, const py::object& progress) {
        const Image test_image = ImageFromArray(test, 0, "compare_images: test");
        const Image reference_image = ImageFromArray(reference, 0, "compare_images: reference");
        std::optional<Image> mask_image;
        if (!mask.is_none()) mask_image = ImageFromArray(mask, 0, "compare_images: mask");
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return CompareImages(test_image, reference_image, mask_image ? &*mask_image : nullptr,
                               options, sink);
        });
      },
      "test"_a, "reference"_a, "mask"_a = py::none(), "options"_a = QualityOptions{},
      "progress"_a = py::none(),
      "Use aos.compare_images. Checks its working memory against the budget (ValueError) and "
      "polls progress / Ctrl-C every band of rows.");

  OptionsClass<ResolutionOptions>(
      m, "ResolutionOptions",
      "Options of sampling_resolution (defaults from the C++ struct aos::ResolutionOptions).")
      .Table()
      .Finish()
      .def("check", &ResolutionOptions::Check, "Raises ValueError naming the field.");

  py::class_<ResolutionResult>(m, "ResolutionResult",
                               "Sampling resolution (Eq. 2, Appendix A) and its effective value.")
      .def_readonly("eq2_samples_per_m2", &ResolutionResult::eq2_samples_per_m2)
      .def_readonly("eq2_sample_size_m", &ResolutionResult::eq2_sample_size_m)
      .def_readonly("samples_per_m2", &ResolutionResult::samples_per_m2)
      .def_readonly("sample_size_m", &ResolutionResult::sample_size_m)
      .def_readonly("pixels_on_plane", &ResolutionResult::pixels_on_plane)
      .def_readonly("pixels_off_axis", &ResolutionResult::pixels_off_axis)
      .def_readonly("footprint_m2", &ResolutionResult::footprint_m2)
      .def_readonly("pose_error_m", &ResolutionResult::pose_error_m)
      .def_readonly("effective_sample_size_m", &ResolutionResult::effective_sample_size_m)
      .def_readonly("effective_samples_per_m2", &ResolutionResult::effective_samples_per_m2)
      .def("__repr__", [](const ResolutionResult& r) {
        return "ResolutionResult(samples_per_m2=" + FormatNumber(r.samples_per_m2) +
               ", sample_size_m=" + FormatNumber(r.sample_size_m) +
               ", eq2_samples_per_m2=" + FormatNumber(r.eq2_samples_per_m2) +
               ", effective_sample_size_m=" + FormatNumber(r.effective_sample_size_m) + ")";
      });

  m.def("_sampling_resolution", &SamplingResolution, "camera"_a, "options"_a,
        "Use aos.sampling_resolution.");
}

}  // namespace aos::python
