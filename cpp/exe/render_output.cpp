#include "render_output.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "aos/image/image_io.h"
#include "aos/util/file_util.h"

namespace fs = std::filesystem;

namespace aos::cli {
namespace {

// The value range that maps onto the integer codes of an 8/16-bit output.
std::pair<double, double> ResolveRange(const std::string& spec, const IntegralResult& result,
                                       PixelType views_type) {
  if (spec == "views") return {0.0, PixelTypeFullRange(views_type)};
  if (spec == "minmax") {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int y = 0; y < result.image.height(); ++y) {
      for (int x = 0; x < result.image.width(); ++x) {
        if (*result.count.At<uint32_t>(x, y) == 0) continue;
        for (int c = 0; c < result.image.channels(); ++c) {
          const double value = result.image.At<float>(x, y)[c];
          lo = std::min(lo, value);
          hi = std::max(hi, value);
        }
      }
    }
    if (!(hi > lo)) return {std::isfinite(lo) ? lo : 0.0, std::isfinite(lo) ? lo + 1.0 : 1.0};
    return {lo, hi};
  }
  const std::vector<double> values = ParseNumbers(spec, "--range", 2);
  return {values[0], values[1]};
}

}  // namespace

void AddRenderOutputFlags(Flags& flags, RenderOutput& out) {
  CLI::App* command = flags.command();
  command->add_option("-o,--output", out.output,
                      "Output image; the extension picks the format: .exr/.tif (float32, as "
                      "rendered), .png (8/16-bit, normalised by --range)")
      ->required();
  command->add_option("--count", out.count,
                      "Also write the per-pixel count of contributing views (.tif uint32, .png "
                      "16-bit, .exr float)");
  AddImageOutputFlags(flags, out.image);
  flags.Output("--output");
  flags.Output("--count");
}

void CheckRenderOutput(const RenderOutput& out, const std::vector<std::string>& inputs) {
  CheckOutputPath(out.output, inputs, "output");
  RefuseExisting(out.output, "output");
  CheckImageOutput(out.image, out.output);
  if (out.count.empty()) return;
  CheckOutputPath(out.count, inputs, "count");
  if (fs::weakly_canonical(fs::absolute(out.count)) ==
      fs::weakly_canonical(fs::absolute(out.output))) {
    ThrowInvalid(out.count + ": --count and --output name the same file");
  }
  RefuseExisting(out.count, "count");
  ResolveSampleType(out.count, Image(1, 1, 1, PixelType::kU32), WriteImageOptions{});
}

void WriteRenderOutput(const IntegralResult& result, const RenderOutput& out,
                       PixelType views_type, const std::vector<std::string>& inputs,
                       Report& report, const std::optional<Radiometry>& radiometry) {
  CheckRenderOutput(out, inputs);
  WriteImageOptions write;
  write.sample_type = ParseSampleType(out.image.sample_type);
  write.units = views_type;  // renders keep the views' units (image_io.h states the rule)
  const auto [lo, hi] = ResolveRange(out.image.range, result, views_type);
  write.range_min = lo;
  write.range_max = hi;
  const SampleType type = ResolveSampleType(out.output, result.image, write);
  std::string how;
  if (type == SampleType::kF32) {
    how = "float32, values as rendered";
  } else {
    how = std::string(SampleTypeName(type)) + ", values " + FormatNumber(lo) + ".." +
          FormatNumber(hi) + " mapped to 0.." + (type == SampleType::kU8 ? "255" : "65535");
  }
  write.description = "aos integral image (" + how + ")";
  if (radiometry) {
    // What a value of the file means in kelvin: the render's values directly (float), or the
    // integer codes through the range they were mapped from.
    Radiometry in_file = *radiometry;
    if (type != SampleType::kF32) {
      const double step = (hi - lo) / (type == SampleType::kU8 ? 255.0 : 65535.0);
      in_file.kelvin_offset = radiometry->Kelvin(lo);
      in_file.kelvin_per_unit = radiometry->kelvin_per_unit * step;
    }
    write.description += "; temperatures: " + in_file.Describe();
  }
  PendingFile image_file(out.output);
  WriteImage(image_file.TempPath(), result.image, write);
  std::optional<PendingFile> count_file;
  if (!out.count.empty()) {
    count_file.emplace(out.count);
    WriteImageOptions count_write;
    count_write.description = "aos count map: views contributing to each pixel";
    WriteImage(count_file->TempPath(), result.count, count_write);
  }
  std::vector<PendingFile*> files{&image_file};
  if (count_file) files.push_back(&*count_file);
  CommitTogether(files);
  report.Set("output", out.output);
  report.Set("width", result.image.width());
  report.Set("height", result.image.height());
  report.Set("sample_type", SampleTypeName(type));
  if (type != SampleType::kF32) report.Set("range", std::vector<double>{lo, hi});
  report.Line("wrote %s (%dx%d, %s)", out.output.c_str(), result.image.width(),
              result.image.height(), how.c_str());
  if (count_file) {
    report.Set("count", out.count);
    report.Line("wrote %s (count of contributing views per pixel)", out.count.c_str());
  }
  if (radiometry && result.image.channels() == 1) {
    std::vector<float> values;
    for (int y = 0; y < result.image.height(); ++y) {
      for (int x = 0; x < result.image.width(); ++x) {
        if (*result.count.At<uint32_t>(x, y) > 0) values.push_back(*result.image.At<float>(x, y));
      }
    }
    if (!values.empty()) {
      std::vector<double> celsius;
      for (double p : {0.01, 0.5, 0.99}) {
        const size_t k = static_cast<size_t>(p * static_cast<double>(values.size() - 1));
        std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k),
                         values.end());
        celsius.push_back(radiometry->Celsius(values[k]));
      }
      report.Set("temperature_c", celsius);
      report.Line("temperatures (%s): covered pixels %.2f .. %.2f C (1st..99th percentile), "
                  "median %.2f C",
                  radiometry->Describe().c_str(), celsius[0], celsius[2], celsius[1]);
    }
  }
}

}  // namespace aos::cli
