#include "aos/sfm/video.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cctype>
#include <cstdlib>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/videoio.hpp>

#include "aos/lightfield/formats.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/geometry/rigid.h"
#include "aos/util/math.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

constexpr double kDeg = kPi / 180.0;

// The angle a + t (b - a) along the shorter arc (InterpolateAngle), degrees, in (-180, 180].
double LerpAngle(double a, double b, double t) {
  double v = std::fmod(InterpolateAngle(a, b, t), 360.0);
  if (v > 180.0) v -= 360.0;
  if (v <= -180.0) v += 360.0;
  return v;
}

// The number after `key` (ASCII, any case) and a ':' (spaces around it allowed) in `lower`
// (the text in lower case), at a word start; nullopt when there is none.
std::optional<double> NumberAfter(const std::string& lower, const std::string& key) {
  for (size_t at = lower.find(key); at != std::string::npos; at = lower.find(key, at + 1)) {
    const unsigned char before = at > 0 ? static_cast<unsigned char>(lower[at - 1]) : ' ';
    if (std::isalnum(before) || before == '_') continue;  // inside another word
    size_t p = at + key.size();
    while (p < lower.size() && lower[p] == ' ') ++p;
    if (p >= lower.size() || lower[p] != ':') continue;
    ++p;
    while (p < lower.size() && lower[p] == ' ') ++p;
    const char* begin = lower.c_str() + p;
    char* end = nullptr;
    const double value = std::strtod(begin, &end);
    if (end == begin || !std::isfinite(value)) continue;
    return value;
  }
  return std::nullopt;
}

// "GPS(lon, lat[, n])" or "GPS (...)" in `lower`: the numbers, or an empty vector.
std::vector<double> GpsTuple(const std::string& lower) {
  size_t at = lower.find("gps");
  while (at != std::string::npos) {
    size_t p = at + 3;
    while (p < lower.size() && lower[p] == ' ') ++p;
    if (p < lower.size() && lower[p] == '(') {
      at = p;
      break;
    }
    at = lower.find("gps", at + 1);
  }
  if (at == std::string::npos) return {};
  std::vector<double> values;
  const char* p = lower.c_str() + at + 1;
  for (int k = 0; k < 3; ++k) {
    while (*p == ' ') ++p;
    char* end = nullptr;
    const double value = std::strtod(p, &end);
    if (end == p || !std::isfinite(value)) break;
    values.push_back(value);
    p = end;
    while (*p == ' ') ++p;
    if (*p != ',') break;
    ++p;
  }
  return values.size() >= 2 ? values : std::vector<double>{};
}

// A time range line "HH:MM:SS,mmm --> ...": its start in seconds; nullopt for another line;
// throws for a range whose start is malformed.
std::optional<double> RangeStart(const std::string& line, const std::string& where) {
  const size_t arrow = line.find("-->");
  if (arrow == std::string::npos) return std::nullopt;
  int hours = 0, minutes = 0, seconds = 0, used = 0;
  char separator = 0;
  const std::string start = line.substr(0, arrow);
  if (std::sscanf(start.c_str(), " %d:%d:%d%c%n", &hours, &minutes, &seconds, &separator,
                  &used) != 4 ||
      (separator != ',' && separator != '.') || hours < 0 || minutes < 0 || minutes > 59 ||
      seconds < 0 || seconds > 59) {
    ThrowInvalid(where + ": time: \"" + line + "\" is not HH:MM:SS,mmm --> HH:MM:SS,mmm");
  }
  std::string millis;
  for (size_t i = static_cast<size_t>(used);
       i < start.size() && std::isdigit(static_cast<unsigned char>(start[i])); ++i) {
    millis += start[i];
  }
  if (millis.empty() || millis.size() > 3) {
    ThrowInvalid(where + ": time: \"" + line + "\" is not HH:MM:SS,mmm --> HH:MM:SS,mmm");
  }
  while (millis.size() < 3) millis += '0';
  return hours * 3600.0 + minutes * 60.0 + seconds + std::stod(millis) / 1000.0;
}

// Metres east and north of `b` from `a` on the WGS84 ellipsoid, through its radii of curvature
// at their mean latitude (to ~1e-6 relative over a frame's step of metres).
Vec2d EastNorth(const SrtSample& a, const SrtSample& b) {
  constexpr double kA = 6378137.0, kE2 = 6.69437999014e-3;  // WGS84 semi-major axis, e^2
  const double lat = 0.5 * (a.latitude_deg + b.latitude_deg) * kDeg;
  const double w = 1.0 - kE2 * std::sin(lat) * std::sin(lat);
  const double meridian = kA * (1.0 - kE2) / (w * std::sqrt(w));  // M
  const double prime_vertical = kA / std::sqrt(w);                  // N
  double dlon = b.longitude_deg - a.longitude_deg;
  if (dlon > 180.0) dlon -= 360.0;
  if (dlon < -180.0) dlon += 360.0;
  return Vec2d(dlon * kDeg * prime_vertical * std::cos(lat),
               (b.latitude_deg - a.latitude_deg) * kDeg * meridian);
}

}  // namespace

SrtLog ReadDjiSrt(const std::string& path, ProgressSink* progress) {
  CheckRegularFile(path, "SRT file");
  std::istringstream stream(ReadTextFile(path));
  std::vector<std::string> lines;
  for (std::string line; std::getline(stream, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  SrtLog log;
  for (size_t i = 0; i < lines.size(); ++i) {
    if ((i & 4095) == 0 && ProgressCancelled(progress)) throw Cancelled();
    const std::string where = path + ": line " + std::to_string(i + 1);
    const std::optional<double> start = RangeStart(lines[i], where);
    if (!start) continue;
    SrtSample s;
    s.line = static_cast<int>(i + 1);
    s.time_s = *start;
    // The block's text in lower case, HTML tags (<font ...>) blanked.
    std::string text;
    size_t j = i + 1;
    for (; j < lines.size() && !lines[j].empty(); ++j) text += lines[j] + " ";
    i = j;
    bool in_tag = false;
    for (char& c : text) {
      if (c == '<') in_tag = true;
      const bool blank = in_tag;
      if (c == '>') in_tag = false;
      c = blank ? ' ' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    std::optional<double> lat = NumberAfter(text, "latitude");
    std::optional<double> lon = NumberAfter(text, "longitude");
    if (!lon) lon = NumberAfter(text, "longtitude");  // some models' spelling
    if (!lat || !lon) {
      // Its third number is not read: a satellite count on some models, an altitude on others.
      const std::vector<double> gps = GpsTuple(text);
      if (!gps.empty()) {
        lon = gps[0];
        lat = gps[1];
      }
    }
    // No position, or DJI's 0, 0 before a GPS fix: skipped.
    if (!lat || !lon || (*lat == 0.0 && *lon == 0.0)) {
      ++log.skipped_blocks;
      continue;
    }
    const std::string at = path + ": line " + std::to_string(s.line);
    if (std::abs(*lat) > 90.0) {
      ThrowInvalid(at + ": latitude: " + FormatNumber(*lat) + " is outside [-90, 90]");
    }
    if (std::abs(*lon) > 180.0) {
      ThrowInvalid(at + ": longitude: " + FormatNumber(*lon) + " is outside [-180, 180]");
    }
    s.latitude_deg = *lat;
    s.longitude_deg = *lon;
    s.relative_altitude_m = NumberAfter(text, "rel_alt");
    if (!s.relative_altitude_m) s.relative_altitude_m = NumberAfter(text, "barometer");
    s.absolute_altitude_m = NumberAfter(text, "abs_alt");
    if (!s.absolute_altitude_m && !s.relative_altitude_m) {
      s.absolute_altitude_m = NumberAfter(text, "altitude");
    }
    const std::optional<double> yaw = NumberAfter(text, "gb_yaw"),
                                pitch = NumberAfter(text, "gb_pitch"),
                                roll = NumberAfter(text, "gb_roll");
    if (yaw && pitch) {
      s.gimbal_yaw_pitch_roll_deg = std::array<double, 3>{*yaw, *pitch, roll.value_or(0.0)};
    }
    if (!log.samples.empty() && !(s.time_s > log.samples.back().time_s)) {
      if (s.time_s == log.samples.back().time_s) continue;  // a repeated block
      ThrowInvalid(at + ": time: " + FormatNumber(s.time_s) + " s comes before the block "
                   "before it (" + FormatNumber(log.samples.back().time_s) + " s)");
    }
    log.samples.push_back(s);
  }
  if (log.samples.size() < 2) {
    ThrowInvalid(path + ": " + std::to_string(log.samples.size()) + " block(s) with a position (" +
                 std::to_string(log.skipped_blocks) + " without): a DJI SRT with latitude and "
                 "longitude per frame is needed, at least two");
  }
  return log;
}

void VideoFramesOptions::Check() const {
  CheckFieldRanges(*this);
  CheckFieldChoices(*this);
  if (srt_file.empty()) ThrowInvalid("srt_file: the video's SRT telemetry is needed");
  if (frame_every_m == 0.0 && !(frame_every_s > 0.0)) {
    ThrowInvalid("frame_every_s: must be > 0 seconds when frames are taken by time "
                 "(frame_every_m 0)");
  }
  if (fixed_pitch_deg && !(std::abs(*fixed_pitch_deg) <= 90.0)) {
    ThrowInvalid("fixed_pitch_deg: must be within [-90, 90] degrees (got " +
                 FormatNumber(*fixed_pitch_deg) + ")");
  }
}

VideoFramesResult ExtractVideoFrames(const std::string& video_path, const std::string& frames_dir,
                                     const std::string& telemetry_csv,
                                     const VideoFramesOptions& options, ProgressSink* progress) {
  options.Check();
  // The video first (a bad one is refused before a long SRT is read), through OpenCV's FFmpeg
  // backend, its log quiet (the other backends' complaints about a file they do not take).
  CheckRegularFile(video_path, "video");
  const cv::utils::logging::LogLevel level =
      cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  cv::VideoCapture capture(video_path, cv::CAP_FFMPEG);
  cv::utils::logging::setLogLevel(level);
  if (!capture.isOpened()) {
    ThrowInvalid(video_path + ": video: OpenCV (FFmpeg) cannot open it (an unknown container or "
                 "codec?)");
  }
  const SrtLog log = ReadDjiSrt(options.srt_file, progress);
  const std::vector<SrtSample>& samples = log.samples;
  VideoFramesResult result;
  result.srt_samples = static_cast<int>(samples.size());
  result.srt_skipped_blocks = log.skipped_blocks;
  const std::string& srt = options.srt_file;

  // Altitudes, per sample.
  const bool relative = options.srt_altitude == "relative";
  std::vector<double> altitudes;
  for (const SrtSample& s : samples) {
    const std::optional<double>& a = relative ? s.relative_altitude_m : s.absolute_altitude_m;
    if (!a) {
      ThrowInvalid(srt + ": line " + std::to_string(s.line) + ": " +
                   (relative ? "rel_alt (or BAROMETER)" : "abs_alt (or GPS's altitude)") +
                   ": missing; srt_altitude '" + options.srt_altitude +
                   "' needs it in every block (give srt_altitude '" +
                   (relative ? "absolute" : "relative") + "'?)");
    }
    altitudes.push_back(*a);
  }
  result.altitude_from = relative ? "SRT rel_alt (above the take-off point)" : "SRT abs_alt";

  // Orientation per sample: the gimbal's, else the course over ground and a fixed pitch.
  const bool gimbal = std::all_of(samples.begin(), samples.end(), [](const SrtSample& s) {
    return s.gimbal_yaw_pitch_roll_deg.has_value();
  });
  std::vector<std::array<double, 3>> angles(samples.size());
  if (gimbal) {
    for (size_t i = 0; i < samples.size(); ++i) angles[i] = *samples[i].gimbal_yaw_pitch_roll_deg;
    result.yaw_from = "SRT gimbal yaw";
    result.pitch_from = "SRT gimbal pitch and roll";
    if (options.fixed_pitch_deg) {
      result.warnings.push_back("fixed_pitch_deg is not used: the SRT has gimbal angles in every "
                                "block");
    }
  } else {
    if (!options.fixed_pitch_deg) {
      ThrowInvalid(srt + ": the SRT has no gimbal angles (gb_yaw, gb_pitch) in every block: give "
                   "fixed_pitch_deg (the camera's pitch, -90 = nadir); the yaw is then the "
                   "direction of flight");
    }
    // Course over ground at each sample, over at least a second of track around it (DJI logs
    // positions to about 0.1 m at up to 30 Hz: neighbours alone give noise, not a course); a
    // hover (under 0.5 m/s) keeps the course before it (or the first defined one).
    std::vector<std::optional<double>> course(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) {
      size_t a = i, b = i;
      while (samples[b].time_s - samples[a].time_s < 1.0 && (a > 0 || b + 1 < samples.size())) {
        if (a > 0) --a;
        if (b + 1 < samples.size()) ++b;
      }
      const Vec2d d = EastNorth(samples[a], samples[b]);
      const double dt = samples[b].time_s - samples[a].time_s;
      if (dt > 0.0 && std::hypot(d.x, d.y) / dt >= 0.5) course[i] = std::atan2(d.x, d.y) / kDeg;
    }
    std::optional<double> first;
    for (const auto& c : course) {
      if (c) {
        first = c;
        break;
      }
    }
    if (!first) {
      ThrowInvalid(srt + ": the drone never moves faster than 0.5 m/s, so the direction of "
                   "flight (the yaw without gimbal angles in the SRT) is never defined");
    }
    double last = *first;
    for (size_t i = 0; i < samples.size(); ++i) {
      if (course[i]) last = *course[i];
      angles[i] = {last, *options.fixed_pitch_deg, 0.0};
    }
    result.yaw_from = "direction of flight (course over ground)";
    result.pitch_from = "fixed_pitch_deg = " + FormatNumber(*options.fixed_pitch_deg) + ", roll 0";
  }

  // Distance flown up to each sample (3-D), for frame_every_m.
  std::vector<double> flown(samples.size(), 0.0);
  for (size_t i = 1; i < samples.size(); ++i) {
    const Vec2d d = EastNorth(samples[i - 1], samples[i]);
    flown[i] = flown[i - 1] + std::sqrt(d.x * d.x + d.y * d.y +
                                        std::pow(altitudes[i] - altitudes[i - 1], 2));
  }

  result.fps = capture.get(cv::CAP_PROP_FPS);
  if (!(result.fps > 0.0) || !std::isfinite(result.fps)) {
    ThrowInvalid(video_path + ": video: no frame rate (fps " + FormatNumber(result.fps) + ")");
  }
  const double frame_count = capture.get(cv::CAP_PROP_FRAME_COUNT);
  ProgressStart(progress, "decode", frame_count > 0 ? static_cast<int64_t>(frame_count) : 0);

  std::string csv = "frame,time,lat,lon,alt,yaw,pitch,roll\n";
  const double t_first = samples.front().time_s, t_last = samples.back().time_s;
  double next_time = t_first, next_distance = -1.0;
  size_t segment = 0;
  cv::Mat frame;
  for (int64_t k = 0; capture.read(frame); ++k) {
    if (ProgressCancelled(progress)) throw Cancelled();
    ProgressAdvance(progress, 1);
    ++result.video_frames;
    if (frame.empty()) continue;
    const double t = static_cast<double>(k) / result.fps + options.srt_offset_s;
    if (t < t_first) continue;
    if (t > t_last) break;
    while (segment + 2 < samples.size() && samples[segment + 1].time_s <= t) ++segment;
    const SrtSample& a = samples[segment];
    const SrtSample& b = samples[segment + 1];
    const double f = std::clamp((t - a.time_s) / (b.time_s - a.time_s), 0.0, 1.0);
    const double distance = flown[segment] + f * (flown[segment + 1] - flown[segment]);
    bool take = false;
    if (options.frame_every_m == 0.0) {
      if (t >= next_time - 1e-6) {  // 1 us: frame times k / fps are rounded
        take = true;
        while (next_time <= t + 1e-6) next_time += options.frame_every_s;
      }
    } else if (next_distance < 0.0 || distance >= next_distance - 1e-6) {  // 1 um: rounding
      take = true;
      next_distance = (next_distance < 0.0 ? distance : next_distance) + options.frame_every_m;
      while (next_distance <= distance + 1e-6) next_distance += options.frame_every_m;
    }
    if (!take) continue;
    char name[32];
    std::snprintf(name, sizeof(name), "%06lld.png", static_cast<long long>(k));
    const std::string path = (fs::path(frames_dir) / name).string();
    if (!cv::imwrite(path, frame)) ThrowInvalid(path + ": cannot write the frame");
    result.width = frame.cols;
    result.height = frame.rows;
    const double lon = a.longitude_deg +
                       f * std::remainder(b.longitude_deg - a.longitude_deg, 360.0);
    char row[320];
    std::snprintf(row, sizeof(row), "%s,%.6f,%.10f,%.10f,%.4f,%.6f,%.6f,%.6f\n", name, t,
                  a.latitude_deg + f * (b.latitude_deg - a.latitude_deg),
                  std::remainder(lon, 360.0),
                  altitudes[segment] + f * (altitudes[segment + 1] - altitudes[segment]),
                  LerpAngle(angles[segment][0], angles[segment + 1][0], f),
                  angles[segment][1] + f * (angles[segment + 1][1] - angles[segment][1]),
                  LerpAngle(angles[segment][2], angles[segment + 1][2], f));
    csv += row;
    result.frames.push_back(name);
    result.times_s.push_back(t);
  }
  if (result.frames.empty()) {
    ThrowInvalid(video_path + ": no frame lies inside the SRT's times [" + FormatNumber(t_first) +
                 ", " + FormatNumber(t_last) + "] s (" + std::to_string(result.video_frames) +
                 " frames at " + FormatNumber(result.fps) + " fps; srt_offset_s " +
                 FormatNumber(options.srt_offset_s) + ")");
  }
  // An SRT that covers much less (or more) than the video is likely another video's: the frames
  // taken would be posed from another flight's log, plausibly. Its block spacing (or 2 s, or 5 %
  // of the video) is allowed: the last block covers the time after its start.
  const double frames_in_video =
      frame_count > 0 ? frame_count : static_cast<double>(result.video_frames);
  const double video_s = frames_in_video / result.fps;
  const double srt_s = t_last + (t_last - t_first) / (samples.size() - 1) - options.srt_offset_s;
  if (std::abs(video_s - srt_s) > std::max(2.0, 0.05 * video_s) ||
      t_first - options.srt_offset_s > 2.0) {
    result.warnings.push_back(
        "the video lasts " + FormatNumber(video_s) + " s but its SRT " + options.srt_file +
        " covers " + FormatNumber(t_first) + " .. " + FormatNumber(t_last) +
        " s (srt_offset_s " + FormatNumber(options.srt_offset_s) +
        "): is it this video's SRT? Only the frames inside the SRT's times were taken");
  }
  WriteTextFileAtomic(telemetry_csv, csv);
  return result;
}

VideoImportResult ImportVideo(const std::string& video_path, const std::string& output_dir,
                              const VideoFramesOptions& options,
                              const TelemetryOptions& telemetry,
                              ProgressSink* progress) {
  options.Check();
  const TelemetryOptions defaults;
  if (!telemetry.telemetry_file.empty() || telemetry.frame_interval_s != 0.0 ||
      telemetry.time_offset_s != 0.0 || telemetry.altitude != defaults.altitude) {
    ThrowInvalid("telemetry: telemetry_file, frame_interval_s, time_offset_s and altitude are "
                 "the video import's own (its telemetry.csv); leave them unset");
  }
  if (telemetry.radiometric != "none") {
    ThrowInvalid("telemetry.radiometric: a video's frames are not radiometric (8-bit, decoded); "
                 "import radiometric frames with import-telemetry");
  }
  TelemetryOptions posing = telemetry;
  posing.telemetry_file = "telemetry.csv";  // checked with a stand-in name before the work
  posing.Check();
  CheckRegularFile(video_path, "video");
  PendingFolder folder(output_dir);
  const fs::path root(folder.TempPath());
  std::error_code error;
  fs::create_directories(root / "frames", error);
  if (error) {
    ThrowInvalid((root / "frames").string() + ": cannot create the folder (" + error.message() +
                 ")");
  }
  VideoImportResult result;
  posing.telemetry_file = (root / "telemetry.csv").string();
  result.frames = ExtractVideoFrames(video_path, (root / "frames").string(),
                                     posing.telemetry_file, options, progress);
  result.telemetry = ImportTelemetry((root / "frames").string(), posing, progress);
  result.telemetry.source = "video";
  result.telemetry.time_source = "the SRT's times (telemetry.csv's time column)";
  if (options.srt_altitude == "relative" && telemetry.altitude_reference == "absolute") {
    result.telemetry.warnings.push_back(
        "altitudes are the SRT's rel_alt (above the take-off point) but altitude_reference is "
        "'absolute': world z is the height above the take-off point, not a DEM's; give "
        "altitude_reference 'takeoff' with takeoff_height_m or dem to focus on a DEM");
  }
  for (const std::string& warning : result.frames.warnings) {
    result.telemetry.warnings.push_back(warning);
  }
  WriteLightField((root / "lightfield.json").string(), result.telemetry.light_field);
  folder.Commit();
  // The light field as written: its frames in output_dir now.
  result.light_field_path = (fs::path(output_dir) / "lightfield.json").string();
  for (View& view : result.telemetry.light_field.views) {
    view.image_path =
        (fs::path(output_dir) / "frames" / fs::path(view.image_path).filename()).string();
  }
  return result;
}

}  // namespace aos
