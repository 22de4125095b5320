// Image quality: metrics.
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <optional>

#include "aos/image/image_io.h"
#include "aos/image/radiometry.h"
#include "aos/metrics/quality.h"
#include "aos/util/error.h"
#include "aos/util/memory.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

struct MetricsCommand {
  std::string test_path;
  std::string reference_path;
  std::string mask_path;
  QualityOptions options;
};

// "test.png against reference.png (mask m.png)": the files a comparison's errors name.
std::string Files(const MetricsCommand& c) {
  return c.test_path + " against " + c.reference_path +
         (c.mask_path.empty() ? std::string() : " (mask " + c.mask_path + ")");
}

// What the comparison will allocate, from the headers alone: the decoded images and
// CompareImages' working memory; refused naming the files before any pixel is decoded.
void CheckMetricsMemory(const MetricsCommand& c) {
  const ImageFileInfo test = ReadImageInfo(c.test_path);
  const ImageFileInfo reference = ReadImageInfo(c.reference_path);
  const auto decoded = [](const ImageFileInfo& info) {
    return SaturatingProduct({static_cast<uint64_t>(info.width), static_cast<uint64_t>(info.height),
                              static_cast<uint64_t>(info.channels), PixelTypeSize(info.type)});
  };
  uint64_t needed = decoded(test);
  const auto add = [&](uint64_t bytes) {
    needed = needed + bytes < needed ? std::numeric_limits<uint64_t>::max() : needed + bytes;
  };
  add(decoded(reference));
  if (!c.mask_path.empty()) add(decoded(ReadImageInfo(c.mask_path)));
  add(CompareImagesWorkingBytes(test.width, test.height, test.channels, test.type,
                                reference.channels, reference.type, c.options));
  CheckMemoryBudget(needed,
                    Files(c) + ": images of " + std::to_string(test.width) + "x" +
                        std::to_string(test.height) + "x" + std::to_string(test.channels) +
                        " pixels",
                    "the decoded images and the SSIM's working planes");
}

int RunMetrics(const MetricsCommand& c, const Flags& flags) {
  flags.NamingFlags([&] { c.options.Check(); });  // before the images are read
  CheckMetricsMemory(c);
  ProgressBar progress(Common().quiet);
  const auto read = [&](const std::string& path) {
    Image image;
    try {
      image = ReadImage(path);
    } catch (const std::bad_alloc&) {
      ThrowInvalid(path + ": not enough memory to decode this image");
    }
    if (progress.Cancelled()) throw Cancelled();  // decoding does not poll; stop before the next
    return image;
  };
  const Image test = read(c.test_path);
  const Image reference = read(c.reference_path);
  std::optional<Image> mask;
  if (!c.mask_path.empty()) mask = read(c.mask_path);
  QualityResult r;
  try {
    r = CompareImages(test, reference, mask ? &*mask : nullptr, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    // Name the files: "compare: the test image is ..." does not say which ones.
    const std::string message = error.what();
    if (message.rfind("compare: ", 0) == 0) ThrowInvalid(Files(c) + ": " + message.substr(9));
    flags.RethrowNamingFlags(error);
  } catch (const std::bad_alloc&) {
    ThrowInvalid(Files(c) + ": not enough memory to compare the images");
  }
  progress.Finish();
  if (!r.note.empty()) Note(r.note);
  Report report("metrics");
  report.Set("mse", r.mse);
  report.Set("psnr_db", r.psnr_db);  // null when the images are identical (infinite PSNR)
  report.Set("ssim", r.ssim);
  report.Set("color_ssim", r.color_ssim);
  report.Set("data_range", r.data_range);
  report.Set("mse_pixels", static_cast<long long>(r.mse_pixels));
  report.Set("ssim_pixels", static_cast<long long>(r.ssim_pixels));
  report.Set("test_scale", r.test_scale);
  // Temperatures: the errors are in the reference's units, which its description may map to
  // kelvin (temperature frames, renders of radiometric light fields).
  std::optional<Radiometry> radiometry =
      RadiometryFromDescription(ReadImageInfo(c.reference_path).description);
  const std::optional<Radiometry> test_radiometry =
      RadiometryFromDescription(ReadImageInfo(c.test_path).description);
  // The errors are in the reference's units only when the test image's values are too.
  if (radiometry && ((test_radiometry && *test_radiometry != *radiometry) || r.test_scale != 1.0)) {
    Note("no RMSE in kelvin: " + c.test_path + "'s values are not in " + c.reference_path +
         "'s temperature units (" +
         (test_radiometry ? test_radiometry->Describe() : "scaled by " + FormatNumber(r.test_scale)) +
         " against " + radiometry->Describe() + ")");
    radiometry.reset();
  }
  char psnr[32];
  std::snprintf(psnr, sizeof(psnr), "%.2f", r.psnr_db);
  report.Result("PSNR %s dB  SSIM %.4f  colour SSIM %.4f  (MSE %s over %lld pixels, SSIM over "
                "%lld, L = %s)",
                std::isfinite(r.psnr_db) ? psnr : "inf", r.ssim, r.color_ssim,
                FormatNumber(r.mse).c_str(), static_cast<long long>(r.mse_pixels),
                static_cast<long long>(r.ssim_pixels), FormatNumber(r.data_range).c_str());
  if (radiometry) {
    const double rmse_k = std::sqrt(r.mse) * radiometry->kelvin_per_unit;
    report.Set("rmse_k", rmse_k);
    report.Line("RMSE %.4f K (= degrees C) in temperature: the reference's values read as %s",
                rmse_k, radiometry->Describe().c_str());
  }
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineMetrics(CLI::App* command) {
  auto c = std::make_shared<MetricsCommand>();
  Flags flags(command);
  command->add_option("test", c->test_path, "Image to assess")->required();
  command->add_option("reference", c->reference_path, "Reference image (ground truth)")
      ->required();
  command->add_option("--mask", c->mask_path,
                      "Only pixels where this image (e.g. a count map) is non-zero");
  QualityOptions& options = c->options;
  flags.Field(options, "data_range");
  flags.Field(options, "gaussian_sigma");
  flags.Field(options, "window_radius");
  flags.Field(options, "k1");
  flags.Field(options, "k2");
  flags.Field(options, "grey");
  flags.Threads();
  flags.Input("test");
  flags.Input("reference");
  flags.Input("--mask");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunMetrics(*c, flags); };
}

}  // namespace aos::cli
