#include "aos/image/flir.h"

#include <cpl_string.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "aos/util/csv.h"
#include "aos/util/error.h"
#include "aos/util/process.h"

namespace aos {
namespace {

using json = nlohmann::json;

// The files of one exiftool call: few enough that a batch's decoded counts stay small (16 frames
// of 640 x 512 are 10 MB) and Ctrl-C is answered within a call.
constexpr size_t kBatch = 16;

// Black-body counts W(T).
double BlackBody(double kelvin, const FlirCalibration& c) {
  return c.planck_r1 / (c.planck_r2 * (std::exp(c.planck_b / kelvin) - c.planck_f)) - c.planck_o;
}

// Transmission of one air path (half the object distance).
double AirTransmission(const FlirCalibration& c) {
  const double t = c.atmospheric_temperature_k - kZeroCelsiusK;
  const double water = c.relative_humidity *
                       std::exp(1.5587 + 0.06939 * t - 0.00027816 * t * t + 0.00000068455 * t * t * t);
  const double root_distance = std::sqrt(c.object_distance_m / 2.0);
  const double root_water = std::sqrt(water);
  return c.x * std::exp(-root_distance * (c.alpha1 + c.beta1 * root_water)) +
         (1.0 - c.x) * std::exp(-root_distance * (c.alpha2 + c.beta2 * root_water));
}

// The counts the scene adds besides the object: raw = gain * W_obj + background.
struct Chain {
  double gain = 1.0;
  double background = 0.0;
};

Chain MakeChain(const FlirCalibration& c) {
  const double tau = AirTransmission(c);  // > 0: FlirCalibration::Check
  const double w = c.window_transmission;
  const double e = c.emissivity;
  const double reflected = BlackBody(c.reflected_temperature_k, c);
  const double air = BlackBody(c.atmospheric_temperature_k, c);
  const double window = BlackBody(c.window_temperature_k, c);
  Chain chain;
  chain.gain = tau * w * tau * e;
  chain.background = tau * w * tau * (1.0 - e) * reflected + tau * w * (1.0 - tau) * air +
                     tau * (1.0 - w) * window + (1.0 - tau) * air;
  return chain;
}

double KelvinOfObjectCounts(double object, const FlirCalibration& c) {
  const double argument = c.planck_r1 / (c.planck_r2 * (object + c.planck_o)) + c.planck_f;
  if (!(object + c.planck_o > 0.0) || !(argument > 0.0)) return std::nan("");
  const double kelvin = c.planck_b / std::log(argument);
  return kelvin > 0.0 && std::isfinite(kelvin) ? kelvin : std::nan("");
}

double Number(const json& entry, const char* tag, const std::string& file, bool required,
              double fallback) {
  const auto it = entry.find(tag);
  if (it == entry.end() || it->is_null()) {
    if (required) {
      ThrowInvalid(file + ": " + tag + ": missing: not a FLIR radiometric image (exiftool found "
                   "no FLIR calibration)");
    }
    return fallback;
  }
  // exiftool -j writes some numbers as strings ("0.00656899996101856").
  double value = 0.0;
  if (it->is_number()) {
    value = it->get<double>();
  } else if (it->is_string()) {
    value = ParseFiniteNumber(it->get<std::string>(), file, tag);
  } else {
    ThrowInvalid(file + ": " + tag + ": expected a number, got " + it->dump());
  }
  if (!std::isfinite(value)) ThrowInvalid(file + ": " + tag + ": not finite");
  return value;
}

// The median of the counts (the 16-bit histogram's).
double MedianCount(const Image& raw, bool swapped) {
  std::vector<int64_t> histogram(65536, 0);
  for (int y = 0; y < raw.height(); ++y) {
    const uint16_t* row = raw.At<uint16_t>(0, y);
    for (int x = 0; x < raw.width(); ++x) {
      const uint16_t v = row[x];
      ++histogram[swapped ? static_cast<uint16_t>((v >> 8) | (v << 8)) : v];
    }
  }
  const int64_t half = (static_cast<int64_t>(raw.width()) * raw.height() + 1) / 2;
  int64_t seen = 0;
  for (int v = 0; v < 65536; ++v) {
    seen += histogram[v];
    if (seen >= half) return v;
  }
  return 65535;
}

bool Plausible(double kelvin) {
  return std::isfinite(kelvin) && kelvin >= kZeroCelsiusK - 100.0 && kelvin <= kZeroCelsiusK + 200.0;
}

FlirFrame DecodeEntry(const json& entry, const std::string& file) {
  FlirFrame frame;
  frame.path = file;
  FlirCalibration& c = frame.calibration;
  c.planck_r1 = Number(entry, "PlanckR1", file, true, 0.0);
  c.planck_r2 = Number(entry, "PlanckR2", file, true, 0.0);
  c.planck_b = Number(entry, "PlanckB", file, true, 0.0);
  c.planck_f = Number(entry, "PlanckF", file, true, 0.0);
  c.planck_o = Number(entry, "PlanckO", file, true, 0.0);
  c.emissivity = Number(entry, "Emissivity", file, true, 1.0);
  c.object_distance_m = Number(entry, "ObjectDistance", file, true, 0.0);
  // exiftool -n gives these in degrees Celsius (its value conversion from the file's kelvin).
  c.reflected_temperature_k =
      Number(entry, "ReflectedApparentTemperature", file, true, 20.0) + kZeroCelsiusK;
  c.atmospheric_temperature_k =
      Number(entry, "AtmosphericTemperature", file, true, 20.0) + kZeroCelsiusK;
  c.window_temperature_k =
      Number(entry, "IRWindowTemperature", file, false,
             c.reflected_temperature_k - kZeroCelsiusK) + kZeroCelsiusK;
  c.window_transmission = Number(entry, "IRWindowTransmission", file, false, 1.0);
  c.relative_humidity = Number(entry, "RelativeHumidity", file, false, 0.5);
  c.alpha1 = Number(entry, "AtmosphericTransAlpha1", file, false, c.alpha1);
  c.alpha2 = Number(entry, "AtmosphericTransAlpha2", file, false, c.alpha2);
  c.beta1 = Number(entry, "AtmosphericTransBeta1", file, false, c.beta1);
  c.beta2 = Number(entry, "AtmosphericTransBeta2", file, false, c.beta2);
  c.x = Number(entry, "AtmosphericTransX", file, false, c.x);
  c.Check(file);

  const auto image = entry.find("RawThermalImage");
  if (image == entry.end() || !image->is_string()) {
    ThrowInvalid(file + ": RawThermalImage: missing: not a FLIR radiometric image");
  }
  std::string data = image->get<std::string>();
  const std::string prefix = "base64:";
  if (data.compare(0, prefix.size(), prefix) != 0) {
    ThrowInvalid(file + ": RawThermalImage: exiftool gave no binary data");
  }
  data.erase(0, prefix.size());
  data.push_back('\0');
  const int bytes = CPLBase64DecodeInPlace(reinterpret_cast<GByte*>(data.data()));
  const cv::Mat encoded(1, bytes, CV_8U, data.data());
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(encoded, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    decoded.release();
  }
  if (decoded.empty() || decoded.type() != CV_16UC1) {
    ThrowInvalid(file + ": RawThermalImage: not a 16-bit one-channel image (" +
                 std::to_string(bytes) + " bytes)");
  }
  const bool png = bytes >= 4 && std::memcmp(data.data(), "\x89PNG", 4) == 0;
  frame.raw_format = png ? "PNG" : "TIFF";
  frame.raw = Image(decoded.cols, decoded.rows, 1, PixelType::kU16);
  frame.raw.CopyFrom(decoded.data, static_cast<ptrdiff_t>(decoded.step1()));  // values apart

  // FLIR stores PNG counts byte-swapped. Which order is right: a thermal image is smooth, and
  // the wrong order turns neighbouring counts that differ in the low byte into values far apart
  // (the low byte becomes the high one), so the order with the smaller mean difference between
  // horizontal neighbours wins; both are then checked for a plausible temperature.
  const auto roughness = [&](bool swapped) {
    double sum = 0.0;
    int64_t n = 0;
    for (int y = 0; y < frame.raw.height(); ++y) {
      const uint16_t* row = frame.raw.At<uint16_t>(0, y);
      for (int x = 1; x < frame.raw.width(); ++x) {
        const auto value = [&](uint16_t v) {
          return swapped ? static_cast<uint16_t>((v >> 8) | (v << 8)) : v;
        };
        sum += std::abs(static_cast<double>(value(row[x])) - value(row[x - 1]));
        ++n;
      }
    }
    return n > 0 ? sum / static_cast<double>(n) : 0.0;
  };
  const Chain chain = MakeChain(c);
  const auto kelvin_of = [&](double raw) {
    return KelvinOfObjectCounts((raw - chain.background) / chain.gain, c);
  };
  bool swap = png;  // FLIR's convention, kept when the image cannot tell (a flat frame)
  const double swapped_roughness = roughness(true), plain_roughness = roughness(false);
  if (swapped_roughness < 0.5 * plain_roughness) swap = true;
  if (plain_roughness < 0.5 * swapped_roughness) swap = false;
  if (swap != png) {
    frame.warnings.push_back(file + ": RawThermalImage (" + frame.raw_format + "): read in " +
                             (swap ? "swapped" : "the file's") + " byte order, not FLIR's usual "
                             "one for it: the other is far from smooth (mean step " +
                             FormatNumber(swap ? plain_roughness : swapped_roughness) +
                             " counts against " +
                             FormatNumber(swap ? swapped_roughness : plain_roughness) + ")");
  }
  const double median = MedianCount(frame.raw, swap);
  if (!Plausible(kelvin_of(median))) {
    ThrowInvalid(file + ": RawThermalImage: the counts give no plausible temperature (median " +
                 FormatNumber(median) + " counts = " +
                 FormatNumber(kelvin_of(median) - kZeroCelsiusK) +
                 " C; -100..200 C expected): check its Planck constants");
  }
  if (swap) {
    for (int y = 0; y < frame.raw.height(); ++y) {
      uint16_t* row = frame.raw.At<uint16_t>(0, y);
      for (int x = 0; x < frame.raw.width(); ++x) {
        row[x] = static_cast<uint16_t>((row[x] >> 8) | (row[x] << 8));
      }
    }
  }
  frame.byte_swapped = swap;
  return frame;
}

// Keeps the lines of exiftool's JSON (which start with one of [ ] { } , or a blank), dropping
// messages ("Error: ...", "Warning: ...") that share its output.
bool JsonLine(const std::string& line) {
  return !line.empty() && std::strchr("[]{}, \t\"", line[0]) != nullptr;
}

}  // namespace

void FlirCalibration::Check(const std::string& where) const {
  const auto positive = [&](double value, const char* tag) {
    if (!(value > 0.0) || !std::isfinite(value)) {
      ThrowInvalid(where + ": " + tag + ": must be > 0 (got " + FormatNumber(value) + ")");
    }
  };
  positive(planck_r1, "PlanckR1");
  positive(planck_r2, "PlanckR2");
  positive(planck_b, "PlanckB");
  if (!std::isfinite(planck_f) || !std::isfinite(planck_o)) {
    ThrowInvalid(where + ": PlanckF, PlanckO: must be finite");
  }
  if (!(emissivity > 0.0 && emissivity <= 1.0)) {
    ThrowInvalid(where + ": Emissivity: must be in (0, 1] (got " + FormatNumber(emissivity) + ")");
  }
  if (!(window_transmission > 0.0 && window_transmission <= 1.0)) {
    ThrowInvalid(where + ": IRWindowTransmission: must be in (0, 1] (got " +
                 FormatNumber(window_transmission) + ")");
  }
  if (!(relative_humidity >= 0.0 && relative_humidity <= 1.0)) {
    ThrowInvalid(where + ": RelativeHumidity: must be in [0, 1] (got " +
                 FormatNumber(relative_humidity) + ")");
  }
  if (!(object_distance_m >= 0.0) || !std::isfinite(object_distance_m)) {
    ThrowInvalid(where + ": ObjectDistance: must be >= 0 metres (got " +
                 FormatNumber(object_distance_m) + ")");
  }
  positive(reflected_temperature_k, "ReflectedApparentTemperature (kelvin)");
  positive(atmospheric_temperature_k, "AtmosphericTemperature (kelvin)");
  positive(window_temperature_k, "IRWindowTemperature (kelvin)");
  for (double value : {alpha1, alpha2, beta1, beta2, x}) {
    if (!std::isfinite(value)) ThrowInvalid(where + ": AtmosphericTrans*: must be finite");
  }
  const double tau = AirTransmission(*this);
  if (!(tau > 0.0 && tau <= 1.5)) {
    ThrowInvalid(where + ": ObjectDistance, RelativeHumidity, AtmosphericTemperature: FLIR's "
                 "atmosphere model gives a transmission of " + FormatNumber(tau) +
                 " over half the distance " + FormatNumber(object_distance_m) +
                 " m (outside the model's range)");
  }
}

double FlirRawOfKelvin(double kelvin, const FlirCalibration& calibration) {
  const Chain chain = MakeChain(calibration);
  return chain.gain * BlackBody(kelvin, calibration) + chain.background;
}

double FlirKelvinOfRaw(double raw, const FlirCalibration& calibration) {
  const Chain chain = MakeChain(calibration);
  return KelvinOfObjectCounts((raw - chain.background) / chain.gain, calibration);
}

std::vector<FlirFrame> ReadFlirFrames(const std::vector<std::string>& paths,
                                      ProgressSink* progress) {
  if (!ProgramExists("exiftool")) {
    ThrowInvalid("exiftool: not found: FLIR radiometric files are read through ExifTool "
                 "(Debian: apt-get install libimage-exiftool-perl)");
  }
  ProgressStart(progress, "flir", static_cast<int64_t>(paths.size()));
  std::vector<FlirFrame> frames;
  frames.reserve(paths.size());
  for (size_t start = 0; start < paths.size(); start += kBatch) {
    const size_t end = std::min(paths.size(), start + kBatch);
    std::vector<std::string> argv{"exiftool", "-q", "-q", "-j", "-n", "-b", "-charset",
                                  "filename=utf8"};
    for (const char* tag :
         {"RawThermalImage", "PlanckR1", "PlanckR2", "PlanckB", "PlanckF", "PlanckO", "Emissivity",
          "ObjectDistance", "ReflectedApparentTemperature", "AtmosphericTemperature",
          "IRWindowTemperature", "IRWindowTransmission", "RelativeHumidity",
          "AtmosphericTransAlpha1", "AtmosphericTransAlpha2", "AtmosphericTransBeta1",
          "AtmosphericTransBeta2", "AtmosphericTransX"}) {
      argv.push_back(std::string("-") + tag);
    }
    argv.push_back("--");
    for (size_t i = start; i < end; ++i) argv.push_back(paths[i]);
    std::string output;
    std::vector<std::string> messages;
    const int status = RunProcess(
        argv,
        [&](const std::string& line) {
          if (JsonLine(line)) {
            output += line;
            output += '\n';
          } else if (messages.size() < 3) {
            messages.push_back(line);
          }
        },
        [&] { return ProgressCancelled(progress); });
    json entries;
    try {
      entries = json::parse(output.empty() ? std::string("[]") : output);
    } catch (const json::exception&) {
      entries = json();
    }
    if (!entries.is_array()) {
      if (end - start > 1) {
        // A message inside the JSON: read the batch file by file, to name the bad one.
        for (size_t i = start; i < end; ++i) {
          std::vector<FlirFrame> one = ReadFlirFrames({paths[i]});
          frames.push_back(std::move(one.front()));
          ProgressAdvance(progress, 1);
        }
        continue;
      }
      ThrowInvalid(paths[start] + ": exiftool gave unreadable output" +
                   (messages.empty() ? std::string() : ": " + messages.front()));
    }
    std::map<std::string, const json*> by_file;
    for (const json& entry : entries) {
      const auto source = entry.find("SourceFile");
      if (entry.is_object() && source != entry.end() && source->is_string()) {
        by_file[source->get<std::string>()] = &entry;
      }
    }
    for (size_t i = start; i < end; ++i) {
      const auto found = by_file.find(paths[i]);
      if (found == by_file.end()) {
        ThrowInvalid(paths[i] + ": exiftool read nothing (exit status " + std::to_string(status) +
                     (messages.empty() ? std::string() : ": " + messages.front()) + ")");
      }
      frames.push_back(DecodeEntry(*found->second, paths[i]));
      ProgressAdvance(progress, 1);
    }
  }
  return frames;
}

Image FlirTemperatureImage(const FlirFrame& frame, const Radiometry& radiometry) {
  radiometry.Check();
  const FlirCalibration& c = frame.calibration;
  const Chain chain = MakeChain(c);
  // One temperature per count: a 16-bit image has at most 65536 distinct values.
  std::vector<int32_t> code_of(65536, -1);
  Image out(frame.raw.width(), frame.raw.height(), 1, PixelType::kU16);
  for (int y = 0; y < frame.raw.height(); ++y) {
    const uint16_t* in = frame.raw.At<uint16_t>(0, y);
    uint16_t* row = out.At<uint16_t>(0, y);
    for (int x = 0; x < frame.raw.width(); ++x) {
      int32_t& code = code_of[in[x]];
      if (code < 0) {
        const double kelvin = KelvinOfObjectCounts((in[x] - chain.background) / chain.gain, c);
        const double value = std::round((kelvin - radiometry.kelvin_offset) / radiometry.kelvin_per_unit);
        if (!std::isfinite(kelvin) || value < 0.0 || value > 65535.0) {
          ThrowInvalid(frame.path + ": RawThermalImage: count " + std::to_string(in[x]) +
                       " at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") " +
                       (std::isfinite(kelvin)
                            ? "is " + FormatNumber(kelvin - kZeroCelsiusK) +
                                  " C, outside the 16-bit range of " + radiometry.Describe()
                            : std::string("gives no temperature (outside the Planck model)")));
        }
        code = static_cast<int32_t>(value);
      }
      row[x] = static_cast<uint16_t>(code);
    }
  }
  return out;
}

}  // namespace aos
