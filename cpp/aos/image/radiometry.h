#pragma once
// Radiometric frames: pixel values that measure temperature.
//
// Contract
// - A Radiometry maps a pixel value v, in the frames' units (0..65535 for 16-bit frames), to a
//   temperature: kelvin = kelvin_per_unit * v + kelvin_offset. The map is linear, so it holds
//   for every average of such values too: an integral image of radiometric views is read with the
//   views' Radiometry.
// - Degrees Celsius are kelvin - 273.15 (kZeroCelsiusK); a temperature difference is the same in
//   kelvin and degrees Celsius.
#include <optional>
#include <string>

namespace aos {

inline constexpr double kZeroCelsiusK = 273.15;

struct Radiometry {
  // Kelvin per unit of pixel value, > 0 (0.01 for frames in centikelvin).
  double kelvin_per_unit = 0.01;
  // Kelvin at pixel value 0, finite.
  double kelvin_offset = 0.0;

  // Throws std::invalid_argument "<where>: kelvin_per_unit: ..." for a bad field.
  void Check(const std::string& where = "radiometry") const;
  double Kelvin(double value) const { return kelvin_per_unit * value + kelvin_offset; }
  double Celsius(double value) const { return Kelvin(value) - kZeroCelsiusK; }
  // The pixel value of a temperature in degrees Celsius (the inverse of Celsius).
  double ValueOfCelsius(double celsius) const {
    return (celsius + kZeroCelsiusK - kelvin_offset) / kelvin_per_unit;
  }
  // "kelvin = 0.01 * value + 0": how an output's values are read, for its description.
  std::string Describe() const;
  bool operator==(const Radiometry& other) const {
    return kelvin_per_unit == other.kelvin_per_unit && kelvin_offset == other.kelvin_offset;
  }
  bool operator!=(const Radiometry& other) const { return !(*this == other); }
};

// The Radiometry an image file's description states ("... kelvin = 0.01 * value + 0 ...", as
// Describe() writes it into temperature frames and renders of radiometric light fields);
// nullopt when the text has none or an invalid one.
std::optional<Radiometry> RadiometryFromDescription(const std::string& text);

}  // namespace aos
