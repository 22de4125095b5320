#pragma once
// Angles: pi and degree/radian conversions, defined once for the core (M_PI is not standard C++).
namespace aos {

inline constexpr double kPi = 3.14159265358979323846;

// Evaluated as x * kPi / 180 (and x * 180 / kPi), as the code they replaced, so results stay
// bit for bit what they were.
constexpr double DegToRad(double degrees) { return degrees * kPi / 180.0; }
constexpr double RadToDeg(double radians) { return radians * 180.0 / kPi; }

}  // namespace aos
