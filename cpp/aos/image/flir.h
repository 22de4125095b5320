#pragma once
// FLIR radiometric JPEGs (and FLIR FFF files): the raw sensor counts and their calibration, read
// through ExifTool (`exiftool` on PATH; Debian's libimage-exiftool-perl), turned into
// temperatures with the Planck relation and FLIR's model of emissivity, atmosphere and window.
//
// The model. Raw counts are proportional to the radiance the sensor receives; a black body at T
// kelvin gives
//   W(T) = R1 / (R2 (exp(B / T) - F)) - O,     and back   T(W) = B / ln(R1 / (R2 (W + O)) + F).
// The camera sees the object (emissivity e) through air of transmission tau, an IR window of
// transmission w (emitting at its own temperature, reflecting nothing) and air again (tau):
//   raw = tau (w (tau (e W_obj + (1 - e) W_refl) + (1 - tau) W_atm) + (1 - w) W_win)
//         + (1 - tau) W_atm
// W_refl, W_atm, W_win being W at the reflected apparent, atmospheric and window temperatures.
// Each air path is half the object distance d:
//   tau = X exp(-sqrt(d/2) (a1 + b1 sqrt(h))) + (1 - X) exp(-sqrt(d/2) (a2 + b2 sqrt(h))),
//   h = humidity exp(1.5587 + 0.06939 t - 0.00027816 t^2 + 0.00000068455 t^3), t the air in C,
// a1, a2, b1, b2, X the camera's constants (AtmosphericTransAlpha1, ...).
//
// Contract
// - FlirKelvinOfRaw inverts FlirRawOfKelvin exactly (up to float64 rounding) for temperatures
//   whose counts lie in the model's domain; a count outside it (W_obj + O <= 0, or a logarithm of
//   a non-positive number) gives NaN.
// - ReadFlirFrames reads each file's RawThermalImage (16-bit PNG or raw data) and its CameraInfo
//   calibration with one exiftool call per batch of files (a batch whose output cannot be read is
//   read again file by file, so the error names the file). FLIR's PNG raw data are stored in the
//   other byte order (little-endian counts in a big-endian PNG) and raw data in the file's: that
//   order is kept unless the other is clearly smoother (a mean step between horizontal
//   neighbours under half: the wrong order scatters neighbouring counts over the 16-bit range),
//   which is then used with a warning. Throws std::invalid_argument naming the file and the tag
//   for a file without FLIR radiometric data, a calibration out of its domain (R1, R2, B <= 0,
//   emissivity or window transmission outside (0, 1], humidity outside [0, 1], a negative
//   distance, an air transmission the model puts outside (0, 1.5]) or counts that give no
//   plausible temperature (-100..+200 C at the median); and naming exiftool when it is missing
//   or fails.
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/image/radiometry.h"
#include "aos/util/progress.h"

namespace aos {

struct FlirCalibration {
  double planck_r1 = 0.0;
  double planck_r2 = 0.0;
  double planck_b = 0.0;
  double planck_f = 1.0;
  double planck_o = 0.0;
  double emissivity = 1.0;
  double object_distance_m = 0.0;
  double reflected_temperature_k = kZeroCelsiusK + 20.0;
  double atmospheric_temperature_k = kZeroCelsiusK + 20.0;
  double window_temperature_k = kZeroCelsiusK + 20.0;
  double window_transmission = 1.0;
  double relative_humidity = 0.5;  // fraction, [0, 1]
  // FLIR's atmospheric transmission constants (the values most FLIR cameras store).
  double alpha1 = 0.006569;
  double alpha2 = 0.01262;
  double beta1 = -0.002276;
  double beta2 = -0.00667;
  double x = 1.9;

  // Throws std::invalid_argument "<where>: <tag>: ..." for a field outside its domain.
  void Check(const std::string& where) const;
};

// Black-body counts of `kelvin` as the camera reports them through the model above.
double FlirRawOfKelvin(double kelvin, const FlirCalibration& calibration);
// The object temperature, kelvin, of a raw count; NaN outside the model's domain.
double FlirKelvinOfRaw(double raw, const FlirCalibration& calibration);

struct FlirFrame {
  std::string path;
  Image raw;                 // kU16, one channel: the sensor counts
  FlirCalibration calibration;
  std::string raw_format;    // "PNG" or "TIFF" (raw data)
  bool byte_swapped = false; // the counts were swapped back from the file's byte order
  std::vector<std::string> warnings;
};

// Reads FLIR radiometric files (see the contract). `progress` gets a "flir" stage, a unit per
// file, and is polled for cancellation (throws aos::Cancelled).
std::vector<FlirFrame> ReadFlirFrames(const std::vector<std::string>& paths,
                                      ProgressSink* progress = nullptr);

// The frame's temperatures as a 16-bit image in the units of `radiometry` (round((kelvin -
// kelvin_offset) / kelvin_per_unit)), border 0. Throws std::invalid_argument naming the file for
// a count with no temperature or a temperature outside the 16-bit range of `radiometry`.
Image FlirTemperatureImage(const FlirFrame& frame, const Radiometry& radiometry);

}  // namespace aos
