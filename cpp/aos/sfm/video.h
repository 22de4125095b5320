#pragma once
// Frames and their telemetry from a drone video with DJI's per-frame subtitle log (.SRT): the
// first half of `aos-render import-video`, which then poses the frames with ImportTelemetry
// (sfm/telemetry.h) from the telemetry CSV written here.
//
// The SRT (ReadDjiSrt): numbered blocks "index / HH:MM:SS,mmm --> HH:MM:SS,mmm / text lines",
// one per video frame or per second. A block's time is its start. From the text (any DJI model's
// layout, HTML tags ignored, keys in any case at a word start, then ':' with spaces allowed):
//   latitude, longitude             "[latitude: 48.12] [longitude: 15.12]", or "GPS(lon, lat, n)"
//                                   (also "GPS (...)"; n, a satellite count on some models, unused)
//   relative altitude (take-off)    "rel_alt: 30.1", or "BAROMETER: 30.1" (older models)
//   absolute altitude               "abs_alt: 350.2", or "altitude: 350.2" alone
//   gimbal yaw, pitch, roll         "gb_yaw: 10.0 gb_pitch: -90.0 gb_roll: 0.0" (where present)
// Blocks without a position are skipped (counted); times must increase.
//
// Frames (ExtractVideoFrames): the video is decoded with OpenCV (its FFmpeg backend: MP4, MOV,
// AVI, ...) sequentially; frame k is at time k / fps (+ srt_offset_s on the SRT's clock). One
// frame is taken every frame_every_s seconds, or (frame_every_m > 0) every frame_every_m metres
// of flight (3-D distance along the SRT track, on the WGS84 ellipsoid), from the first frame the
// SRT covers to the last; each is written as "<frames_dir>/<k, 6 digits>.png" (8-bit, the
// video's colour) and its telemetry interpolated linearly between the SRT samples around its
// time (yaw and longitude along the shorter arc).
// Orientation: the SRT's gimbal angles where every sample has them (fixed_pitch_deg is then
// unused, with a warning); else yaw = the direction of flight (course over ground over at least
// a second of track around the sample; a hover under 0.5 m/s keeps the last course), pitch =
// fixed_pitch_deg (required then), roll 0: what the summary states (VideoFramesResult::yaw_from,
// pitch_from).
//
// A warning (VideoFramesResult::warnings) says when the SRT's span and the video's length differ
// by more than 2 s and 5 % of the video, or the SRT starts more than 2 s into it: likely another
// video's SRT, or one out of sync (srt_offset_s).
//
// The telemetry CSV (telemetry_csv) has the columns frame, time, lat, lon, alt, yaw, pitch, roll,
// one row per frame written, and is what ImportTelemetry reads (a frame column with capture
// times). alt is the SRT's relative altitude (srt_altitude "relative", above the take-off point:
// import it with altitude_reference "takeoff") or its absolute one ("absolute").
//
// Throws std::invalid_argument naming the file, the block (line) and the field: an SRT without
// positions, a malformed time, times that decrease, a video OpenCV cannot open or that has no
// frame rate, no frame inside the SRT's times, gimbal angles missing with no fixed_pitch_deg, a
// course that never becomes defined (the drone never moves); aos::Cancelled when the progress
// sink asks to stop (polled once per decoded frame).
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "aos/sfm/telemetry.h"
#include "aos/util/option_fields.h"
#include "aos/util/progress.h"

namespace aos {

struct SrtSample {
  int line = 0;          // the line of the block's time range
  double time_s = 0.0;   // the block's start, seconds
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  std::optional<double> relative_altitude_m;
  std::optional<double> absolute_altitude_m;
  std::optional<std::array<double, 3>> gimbal_yaw_pitch_roll_deg;
};

struct SrtLog {
  std::vector<SrtSample> samples;
  int skipped_blocks = 0;  // blocks without a position
};

// Polls `progress` for cancellation every 4096 lines (throws aos::Cancelled).
SrtLog ReadDjiSrt(const std::string& path, ProgressSink* progress = nullptr);

struct VideoFramesOptions {
  // DJI's subtitle telemetry (.SRT) of the video.
  std::string srt_file;
  // Take a frame every this many seconds of video, > 0 (when frame_every_m is 0).
  double frame_every_s = 1.0;
  // Take a frame every this many metres of flight instead, > 0; 0 = by time (frame_every_s).
  double frame_every_m = 0.0;
  // The SRT's altitude written as alt: "relative" (above the take-off point) or "absolute".
  std::string srt_altitude = "relative";
  // The camera's pitch when the SRT has no gimbal angles, degrees (-90 = nadir); unset = none.
  std::optional<double> fixed_pitch_deg;
  // The SRT time of the video's first frame, seconds (when the two clocks differ).
  double srt_offset_s = 0.0;
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = VideoFramesOptions;
    field(OptionField("srt_file", &O::srt_file, "", Range::Any(),
                      "DJI subtitle telemetry (.SRT) of the video: time, position, altitudes, "
                      "gimbal angles where present."));
    field(OptionField("frame_every_s", &O::frame_every_s, "s", Range::FiniteAtLeast(0.0),
                      "Take a frame every this many seconds of video (frame_every_m 0)."));
    field(OptionField("frame_every_m", &O::frame_every_m, "m", Range::FiniteAtLeast(0.0),
                      "Take a frame every this many metres of flight instead; 0 = by time."));
    field(OptionField("srt_altitude", &O::srt_altitude, "", Range::OneOf("relative|absolute"),
                      "Which SRT altitude becomes alt: 'relative' (above the take-off point) "
                      "or 'absolute'."));
    field(OptionField("fixed_pitch_deg", &O::fixed_pitch_deg, "deg", Range::Any(),
                      "Camera pitch when the SRT has no gimbal angles (-90 = nadir); the yaw "
                      "is then the direction of flight."));
    field(OptionField("srt_offset_s", &O::srt_offset_s, "s", Range::Finite(),
                      "The SRT time of the video's first frame, seconds."));
  }
};

struct VideoFramesResult {
  std::vector<std::string> frames;  // file names written into frames_dir, in time order
  std::vector<double> times_s;      // their times in the video, seconds
  int64_t video_frames = 0;         // frames decoded
  double fps = 0.0;
  int width = 0, height = 0;
  int srt_samples = 0, srt_skipped_blocks = 0;
  std::string yaw_from;    // "SRT gimbal yaw" or "direction of flight"
  std::string pitch_from;  // "SRT gimbal pitch" or "fixed_pitch_deg = -90"
  std::string altitude_from;  // "SRT rel_alt (above the take-off point)" or "SRT abs_alt"
  std::vector<std::string> warnings;  // options not used, ...
};

VideoFramesResult ExtractVideoFrames(const std::string& video_path, const std::string& frames_dir,
                                     const std::string& telemetry_csv,
                                     const VideoFramesOptions& options,
                                     ProgressSink* progress = nullptr);

struct VideoImportResult {
  VideoFramesResult frames;
  TelemetryResult telemetry;   // its light field as written (image paths in output_dir)
  std::string light_field_path;  // output_dir/lightfield.json
};

// `aos-render import-video`: into the new folder output_dir (refused when it exists and is not
// empty; written under a temporary name and renamed when complete, so a failure leaves nothing)
// ExtractVideoFrames writes frames/ and telemetry.csv, ImportTelemetry poses the frames from it
// with `telemetry` (its telemetry_file, frame_interval_s, time_offset_s and altitude must be
// left at their defaults: the CSV is this import's), and the light field is written as
// lightfield.json. A warning is added when the SRT's relative altitudes are taken as absolute.
VideoImportResult ImportVideo(const std::string& video_path, const std::string& output_dir,
                              const VideoFramesOptions& options,
                              const TelemetryOptions& telemetry,
                              ProgressSink* progress = nullptr);

}  // namespace aos
