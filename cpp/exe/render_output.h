#pragma once
#include <optional>
// Writing one rendered image and its count map (integral, demo): -o, --count, --sample-type and
// --range, checked before any work and written atomically together.
#include <string>
#include <vector>

#include "aos/render/integral.h"
#include "cli.h"

namespace aos::cli {

struct RenderOutput {
  std::string output;  // image path; the extension picks the format
  std::string count;   // count map path, or empty
  ImageOutputOptions image;
};

// -o/--output (required), --count, --sample-type, --range.
void AddRenderOutputFlags(Flags& flags, RenderOutput& out);

// Checks the output paths before any work: folders exist, no output is an input, the two
// outputs differ, existing files need --force, and each extension can hold its samples.
void CheckRenderOutput(const RenderOutput& out, const std::vector<std::string>& inputs);

// Writes the image (and count map) of `result`: both go to temporary files first and are moved
// into place only when both are complete, so a failure leaves neither. Adds the outputs to
// `report` ("output", "count", "sample_type", "range", and a line each). With `radiometry` (the
// light field's: the values measure temperature) the file's description says how its values
// read as kelvin, and the report gives the covered pixels' temperatures in degrees Celsius
// ("temperature_c": 1st, 50th and 99th percentile).
void WriteRenderOutput(const IntegralResult& result, const RenderOutput& out,
                       PixelType views_type, const std::vector<std::string>& inputs,
                       Report& report,
                       const std::optional<Radiometry>& radiometry = std::nullopt);

}  // namespace aos::cli
