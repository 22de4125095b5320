// The live command: in-flight integration of a replayed light field or a watched frames
// folder (cpp/aos/live/live.h; docs/live.md).
#include <algorithm>
#include <chrono>
#include <map>
#include <set>
#include <thread>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>

#include <poll.h>
#include <sys/stat.h>
#include <sys/inotify.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <csignal>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <nlohmann/json.hpp>

#include "aos/detect/detect.h"
#include "aos/live/live.h"
#include "aos/sfm/telemetry.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/formats.h"
#include "aos/lightfield/options_json.h"
#include "aos/viewer/viewer_options.h"
#include "aos/render/integral.h"
#include "aos/render/map.h"
#include "aos/util/csv.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"
#include "render_flags.h"
#include "render_output.h"

namespace fs = std::filesystem;

namespace aos::cli {

namespace {

struct LiveCommand {
  std::string source;     // FRAMES_DIR (watched)
  std::string replay;     // --replay LIGHTFIELD
  double fps = 0.0;       // --fps: replay pace; 0 = as fast as the updates run
  double idle_exit_s = 0.0;  // --idle-exit-s: stop after this long without a new frame; 0 = never
  double poll_s = 0.1;
  bool exif = false;     // --exif: poses from the frames' own GPS and gimbal tags
  bool resume = false;   // --resume: the tracks of --geojson carried on, the folder's backlog skipped
  LoadOptions load;
  std::string focal_surface_path;
  RenderArgs args;
  IntegralOptions options;
  DetectOptions detect;
  LiveOptions live;
  TelemetryOptions telemetry;
  MapOptions map;        // --follow map: the area (extent, pixel size); the rest from `options`
  std::string geojson, csv, image;
  bool view = false;     // --view: serve the live page (Python's aos.viewer on a state folder)
  ViewerOptions viewer;
  bool no_browser = false;
};

// `--view`: the live page's server, a child process (Python running aos.viewer's main with a
// --spec with "live_dir"), reading the state folder this process writes after every update. Stopped
// (SIGTERM, then waited for) and the folder removed when this goes.
class LivePage {
 public:
  LivePage(const ViewerOptions& viewer, bool quiet) {
    folder_ = MakePrivateTempFolder("aos-live-view-", "--view");
    nlohmann::ordered_json spec;
    spec["live_dir"] = folder_;
    spec["url_to_stderr"] = true;  // stdout is the live command's (its --json report)
    spec["viewer"] = OptionsToJson(viewer);
    spec["quiet"] = quiet;
    spec["json"] = false;
    const std::string python = FindPython("live --view", "viewer");
    const std::string text = spec.dump();
    std::fflush(stdout);
    std::fflush(stderr);
    pid_ = ::fork();
    if (pid_ < 0) ThrowInvalid(std::string("--view: cannot start the viewer: ") + std::strerror(errno));
    if (pid_ == 0) {
      ::signal(SIGINT, SIG_IGN);  // the parent stops it (SIGTERM) when the run ends
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);  // and if the parent dies first (a kill, the backstop)
      if (::getppid() == 1) ::_exit(0);
      const std::string launcher = PythonLauncher("live --view", "viewer");
      ::execlp(python.c_str(), python.c_str(), "-c", launcher.c_str(), "--spec", text.c_str(),
               static_cast<char*>(nullptr));
      ::_exit(127);
    }
  }
  ~LivePage() {
    if (pid_ > 0) {
      // SIGTERM, and SIGKILL after 0.8 s: the CLI ends within 1.5 s of a signal.
      ::kill(pid_, SIGTERM);
      int status = 0;
      for (int i = 0; i < 80 && ::waitpid(pid_, &status, WNOHANG) == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      if (::waitpid(pid_, &status, WNOHANG) == 0) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
      }
    }
    std::error_code error;
    fs::remove_all(folder_, error);
  }
  LivePage(const LivePage&) = delete;
  LivePage& operator=(const LivePage&) = delete;
  // The newest update: its image (alternating names, so a reader's image is never replaced
  // while it reads it by name) and live.json, each renamed into place.
  void Write(const LiveIntegrator& integrator, double frame_seen_unix, double update_ms) {
    const DetectResult result = integrator.result();
    nlohmann::ordered_json state = nlohmann::ordered_json::parse(integrator.StateJson());
    if (!result.render.image.empty()) {
      const std::string name = "live-" + std::to_string(state["update"].get<int>() % 2) + ".png";
      PendingFile file((fs::path(folder_) / name).string());
      WriteImage(file.TempPath(), DetectionOverlay(result), WriteImageOptions{});
      file.Commit();
      state["image"] = name;
    }
    state["frame_seen_unix"] = frame_seen_unix;
    state["update_ms"] = update_ms;
    WriteTextFileAtomic((fs::path(folder_) / "live.json").string(), state.dump());
  }
  bool Running() {
    if (pid_ > 0 && ::waitpid(pid_, nullptr, WNOHANG) != 0) pid_ = -1;  // ended (reaped)
    return pid_ > 0;
  }

 private:
  std::string folder_;
  pid_t pid_ = -1;
};

double UnixSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// One frame file being watched: its size and modification time at the last poll.
struct Watched {
  uintmax_t size = 0;
  fs::file_time_type mtime{};
  int stable_polls = 0;
  bool done = false;         // taken, or skipped for good
  bool failed = false;       // could not be decoded at this size and time
  double first_seen_s = 0.0;
  double seen_unix = 0.0;    // when it was first seen, seconds since 1970 (the page's latency)
  int index = -1;            // its place in the flight: frames in the order they arrived (those
                             // in the folder at the start, and those seen in one poll, by name)
};

// Whether a folder entry can be a frame: a frame file type, not hidden, not a partial download.
bool FrameName(const fs::path& path) {
  const std::string name = path.filename().string();
  if (name.empty() || name[0] == '.') return false;
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  for (const char* e : {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr"}) {
    if (extension == e) return true;
  }
  return false;
}

// The telemetry log as a live run reads it, re-read on every poll (it may lag the frames).
// A last line without its line end is a row still being written: left for the next read.
struct LiveLog {
  std::string path;
  std::vector<CsvRecord> records;  // [0] = the header
  int frame_column = -1;           // frame (name, image, file): each row names its frame
  int time_column = -1;            // time without a frame column: frames placed by time
  std::vector<double> times;       // with time_column: each row's time (records[r + 1])
};

// Appends the complete lines of `text` (a line from `first_line` on; a last line without its
// line end is left out by the caller) to `log`: the header first, then rows; a time log's
// times are parsed and must increase. All or nothing: on an error `log` is as it was.
void AppendLiveLog(const std::string& text, int first_line, LiveLog* log) {
  const std::string& path = log->path;
  std::vector<CsvRecord> records = ParseCsv(text, path);
  for (CsvRecord& record : records) record.line += first_line - 1;
  int frame_column = log->frame_column, time_column = log->time_column;
  const bool had_header = !log->records.empty();
  if (!had_header) {
    if (records.empty()) ThrowInvalid(path + ": no header line");
    int any_time = -1;
    for (size_t k = 0; k < records[0].fields.size(); ++k) {
      std::string field = records[0].fields[k];
      std::transform(field.begin(), field.end(), field.begin(),
                     [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
      if (field == "frame" || field == "name" || field == "image" || field == "file") {
        frame_column = static_cast<int>(k);
      }
      if (field == "time") any_time = static_cast<int>(k);
    }
    if (frame_column < 0 && any_time < 0) {
      ThrowInvalid(path + ": line " + std::to_string(records[0].line) +
                   ": the header needs a frame column (frame names) or a time column (seconds)");
    }
    if (frame_column < 0) time_column = any_time;
  }
  std::vector<double> times;
  if (time_column >= 0) {
    double last = log->times.empty() ? -std::numeric_limits<double>::infinity() : log->times.back();
    for (size_t r = had_header ? 0 : 1; r < records.size(); ++r) {
      const CsvRecord& record = records[r];
      const std::string where = path + ": line " + std::to_string(record.line);
      if (static_cast<size_t>(time_column) >= record.fields.size()) {
        ThrowInvalid(where + ": time: missing");
      }
      const double t =
          ParseFiniteNumber(record.fields[static_cast<size_t>(time_column)], where, "time");
      if (!(t > last)) {
        ThrowInvalid(where + ": time: " + FormatNumber(t) +
                     " does not increase (the line before has " + FormatNumber(last) + ")");
      }
      times.push_back(t);
      last = t;
    }
  }
  log->frame_column = frame_column;
  log->time_column = time_column;
  log->records.insert(log->records.end(), std::make_move_iterator(records.begin()),
                      std::make_move_iterator(records.end()));
  log->times.insert(log->times.end(), times.begin(), times.end());
}

// The whole log, its complete lines (a last line without its line end is a row still being
// written: left for the next read).
LiveLog ReadLiveLog(const std::string& path) {
  LiveLog log;
  log.path = path;
  std::string whole = ReadTextFile(path);
  const size_t end = whole.find_last_of('\n');
  whole.resize(end == std::string::npos ? 0 : end + 1);
  AppendLiveLog(whole, 1, &log);
  return log;
}

// The log as it grows: each Read parses only the complete lines appended since the last one
// (a flight controller's log at 100 Hz holds hundreds of thousands of rows, and a waiting frame
// reads it every poll). A log that was replaced (another file) or shortened is read again from
// its start (a log rewritten in place to the same length or longer is not noticed: flight
// loggers append). A read that fails leaves the last good state for the next try.
class LiveLogReader {
 public:
  explicit LiveLogReader(std::string path) : path_(std::move(path)) {}

  const LiveLog& Read() {
    struct stat now {};
    if (::stat(path_.c_str(), &now) != 0) {
      ThrowInvalid(path_ + ": cannot read the telemetry log: " + std::strerror(errno));
    }
    const bool same_file = log_ && now.st_ino == inode_ && now.st_dev == device_ &&
                           static_cast<uintmax_t>(now.st_size) >= consumed_;
    if (!same_file) {  // the first read, or another file: from its start
      log_.reset();
      consumed_ = 0;
      lines_ = 0;
    }
    // ReadTextFile's checks: a regular file (never a FIFO that would block), of bounded size.
    std::string tail = ReadTextFile(path_, kMaxTextFileBytes, consumed_);
    const size_t end = tail.find_last_of('\n');
    tail.resize(end == std::string::npos ? 0 : end + 1);
    if (!log_) {
      LiveLog first;
      first.path = path_;
      AppendLiveLog(tail, 1, &first);  // throws for a log without its header line yet
      log_ = std::move(first);
    } else if (!tail.empty()) {
      AppendLiveLog(tail, lines_ + 1, &*log_);  // all or nothing
    }
    consumed_ += tail.size();
    lines_ += static_cast<int>(std::count(tail.begin(), tail.end(), '\n'));
    inode_ = now.st_ino;
    device_ = now.st_dev;
    return *log_;
  }

 private:
  std::string path_;
  std::optional<LiveLog> log_;
  uintmax_t consumed_ = 0;  // bytes of complete lines parsed
  int lines_ = 0;           // lines in them
  ino_t inode_ = 0;
  dev_t device_ = 0;
};

std::string CsvLine(const CsvRecord& record) {
  std::string text;
  for (size_t k = 0; k < record.fields.size(); ++k) {
    text += (k ? "," : "") + CsvField(record.fields[k]);
  }
  return text + "\n";
}

// A log with a frame column: its header and the rows that name one of `names` (a file name, or
// a path ending in it), as CSV text; `found` gets the names it has rows for.
std::string LogRowsNaming(const LiveLog& log, const std::vector<std::string>& names,
                          std::set<std::string>* found) {
  const std::set<std::string> wanted(names.begin(), names.end());
  const size_t column = static_cast<size_t>(log.frame_column);
  std::string text = CsvLine(log.records[0]);
  for (size_t r = 1; r < log.records.size(); ++r) {
    const std::vector<std::string>& fields = log.records[r].fields;
    if (column < fields.size() && wanted.count(fs::path(fields[column]).filename().string()) > 0) {
      text += CsvLine(log.records[r]);
      found->insert(fs::path(fields[column]).filename().string());
    }
  }
  return text;
}

// A log with a time column only: its header and the rows around time `t` (the last at or
// before it and, unless that one is at `t`, the next), which ImportTelemetry interpolates
// between; "" when the log does not reach `t` yet. `before_start`: `t` precedes its first row.
std::string LogRowsAround(const LiveLog& log, double t, bool* before_start) {
  *before_start = !log.times.empty() && t < log.times.front();
  // k: the rows at or before t (times increase: ReadLiveLog checks).
  const size_t k = static_cast<size_t>(
      std::upper_bound(log.times.begin(), log.times.end(), t) - log.times.begin());
  if (k == 0) return "";                 // before the first row, or no rows yet
  if (log.times[k - 1] == t) return CsvLine(log.records[0]) + CsvLine(log.records[k]);
  if (k == log.times.size()) return "";  // after the last row: the log lags
  return CsvLine(log.records[0]) + CsvLine(log.records[k]) + CsvLine(log.records[k + 1]);
}

// The tracks a live run wrote as GeoJSON (WriteDetections with sightings), for --resume.
std::vector<LiveTrack> ReadTracks(const std::string& path, std::string* crs) {
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(ReadTextFile(path));
  } catch (const nlohmann::json::exception& error) {
    ThrowInvalid(path + ": --resume: not JSON (" + error.what() + ")");
  }
  std::vector<LiveTrack> tracks;
  if (!root.contains("features") || !root["features"].is_array()) {
    ThrowInvalid(path + ": --resume: features: missing (not the GeoJSON of a live run)");
  }
  for (size_t i = 0; i < root["features"].size(); ++i) {
    const std::string where = path + ": --resume: features/" + std::to_string(i) + "/properties";
    try {
      const nlohmann::json& p = root["features"][i].at("properties");
      LiveTrack track;
      Detection& d = track.detection;
      if (p.at("local").is_null()) continue;  // not located: no place to carry on
      const auto local = p.at("local").get<std::array<double, 3>>();
      const auto world = p.at("world").get<std::array<double, 3>>();
      d.local = Vec3d(local[0], local[1], local[2]);
      d.world = Vec3d(world[0], world[1], world[2]);
      d.pixel = Vec2d(p.at("pixel_x").get<double>(), p.at("pixel_y").get<double>());
      d.area_px = p.at("area_px").get<int>();
      d.peak_score = p.at("peak_score").get<double>();
      d.mean_score = p.at("mean_score").get<double>();
      const nlohmann::json& geometry = root["features"][i].at("geometry");
      if (!geometry.is_null()) {
        const auto lon_lat = geometry.at("coordinates").get<std::array<double, 2>>();
        d.lon_lat = Vec2d(lon_lat[0], lon_lat[1]);
      }
      if (crs->empty()) *crs = p.value("crs", std::string());
      track.sightings = p.value("sightings", 1);
      track.first_frame = p.value("first_seen", std::string());
      track.last_frame = p.value("last_seen", std::string());
      tracks.push_back(std::move(track));
    } catch (const nlohmann::json::exception& error) {
      ThrowInvalid(where + ": " + error.what());
    }
  }
  return tracks;
}

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  return values[static_cast<size_t>(std::lround(p * static_cast<double>(values.size() - 1)))];
}

int RunLive(LiveCommand& c, const Flags& flags) {
  if (c.replay.empty() == c.source.empty()) {
    ThrowUsage("live: give a frames folder to watch, or --replay LIGHTFIELD (not both)");
  }
  if (c.geojson.empty() && c.csv.empty() && c.image.empty()) {
    ThrowUsage("--geojson, --csv, --image: give at least one output");
  }
  if (!(c.fps >= 0.0 && std::isfinite(c.fps))) ThrowUsage("--fps: must be >= 0");
  if (!(c.idle_exit_s >= 0.0 && std::isfinite(c.idle_exit_s))) {
    ThrowUsage("--idle-exit-s: must be >= 0");
  }
  flags.NamingFlags([&] {
    c.live.Check();
    if (c.live.detect) c.detect.Check();
  });
  std::vector<std::string> inputs;
  if (!c.replay.empty()) inputs.push_back(c.replay);
  if (!c.source.empty()) inputs.push_back(c.source);
  if (!c.telemetry.telemetry_file.empty()) inputs.push_back(c.telemetry.telemetry_file);
  for (const auto& [path, what] : std::vector<std::pair<std::string, const char*>>{
           {c.geojson, "geojson"}, {c.csv, "csv"}, {c.image, "image"}}) {
    if (path.empty()) continue;
    CheckOutputPath(path, inputs, what);
    if (!c.resume) RefuseExisting(path, what);  // a resumed run rewrites its own outputs
  }
  for (const std::string* path : {&c.geojson, &c.csv}) {
    if (!path->empty()) CheckDetectionsPath(*path, "EPSG:4326");
  }
  if (c.resume && (c.geojson.empty() || !c.replay.empty())) {
    ThrowUsage("--resume: continues a folder run from its --geojson tracks (give both)");
  }
  std::vector<LiveTrack> resumed;
  std::string resumed_crs;
  if (c.resume && fs::exists(c.geojson)) resumed = ReadTracks(c.geojson, &resumed_crs);
  if (!c.image.empty()) ResolveSampleType(c.image, Image(1, 1, 1, PixelType::kU8), WriteImageOptions{});
  ReadFocalSurface(c.args.focal_surface, &c.options.focal_surface);
  if (!c.args.cam_from_world.empty()) {
    const std::vector<double> v = ParseNumbers(c.args.cam_from_world, "--cam-from-world", 12);
    std::array<double, 12> m{};
    std::copy(v.begin(), v.end(), m.begin());
    c.options.cam_from_world = Rigid3d::FromMatrix3x4(m);
  } else if (c.live.follow == "fixed") {
    ThrowUsage("--follow fixed: give the virtual camera with --cam-from-world");
  }
  ProgressBar progress(/*quiet=*/true);
  std::unique_ptr<LivePage> page;
  if (c.view) {
    if (c.no_browser) c.viewer.open_browser = false;
    flags.At("viewer.").NamingFlags([&] { c.viewer.Check(); });
    page = std::make_unique<LivePage>(c.viewer, Common().quiet);
  }
  // The light field every view joins: the replayed one's, or the first imported batch's.
  std::optional<LightField> replayed;
  std::unique_ptr<LiveIntegrator> integrator;
  std::vector<double> update_ms;
  int frames = 0, skipped = 0, backlog = 0;
  const auto start = std::chrono::steady_clock::now();
  const auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const auto write_outputs = [&] {
    const DetectResult tracks = integrator->TracksResult();
    for (const std::string* path : {&c.geojson, &c.csv}) {
      if (!path->empty()) WriteDetections(*path, tracks, /*overwrite=*/true);
    }
    if (!c.image.empty() && !integrator->result().render.image.empty()) {
      PendingFile file(c.image);
      WriteImageOptions write;
      write.description = "aos live integral (8-bit preview, 1st..99th percentile)";
      WriteImage(file.TempPath(), DetectionOverlay(integrator->result()), write);
      file.Commit();
    }
  };
  // The integrator: a camera's integral, or (--follow map) the map of --extent, which takes the
  // aperture, focus, threads and (without --pixel-size) width of the render flags.
  const auto make_integrator = [&](const LightField& base) {
    return flags.NamingFlags([&] {
      if (c.live.follow != "map") {
        return std::make_unique<LiveIntegrator>(base, c.options, c.detect, c.live);
      }
      MapOptions map = c.map;
      static_cast<ApertureOptions&>(map) = c.options;
      map.focal_surface = c.options.focal_surface;
      map.surface_offset = c.options.surface_offset;
      if (map.pixel_size == 0.0) map.width = c.options.width > 0 ? c.options.width : 512;
      return std::make_unique<LiveIntegrator>(base, map, c.detect, c.live);
    });
  };
  // `time_s`: the frame's time for --window-s (seconds since the run began: its arrival, or its
  // place in a paced replay).
  const auto add = [&](View view, double seen_unix, double time_s) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::string name = view.name;
    try {
      flags.NamingFlags([&] { integrator->Add(std::move(view), true, &progress, time_s); });
    } catch (const Cancelled&) {
      return;  // stopped within this update: the outputs stay those of the last one
    }
    write_outputs();
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (page) page->Write(*integrator, seen_unix, ms);
    update_ms.push_back(ms);
    ++frames;
    if (!Common().quiet && !Common().json) {
      std::fprintf(stderr, "live: %s: window %zu, %zu detections, %zu tracks, %.1f ms\n",
                   name.c_str(), integrator->window().views.size(),
                   integrator->result().detections.size(), integrator->tracks().size(), ms);
    }
  };
  if (!c.replay.empty()) {
    LoadOptions load = c.load;
    load.load_images = false;
    load.num_threads = c.options.num_threads;
    replayed = flags.At("load.").NamingFlags([&] { return LoadLightField(c.replay, load).light_field; });
    if (replayed->views.empty()) ThrowInvalid(c.replay + ": views: none to replay");
    integrator = make_integrator(*replayed);
    for (int i = 0; i < static_cast<int>(replayed->views.size()); ++i) {
      if (Interrupted()) break;
      if (c.fps > 0.0) {
        const double due = i / c.fps;
        while (seconds() < due && !Interrupted()) {  // in slices: a signal stops it at once
          std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.05, due - seconds())));
        }
        if (Interrupted()) break;
      }
      const double seen = UnixSeconds();
      LoadViewImages(*replayed, {i}, load);
      View view = replayed->views[static_cast<size_t>(i)];
      DropViewImages(*replayed, {i});  // the window holds the one copy it needs
      add(std::move(view), seen, c.fps > 0.0 ? i / c.fps : seconds());
    }
  } else {
    if (!fs::is_directory(c.source)) ThrowInvalid(c.source + ": not a folder");
    if (c.telemetry.telemetry_file.empty() == !c.exif) {
      ThrowUsage("live " + c.source + ": give --telemetry-file LOG (a CSV with a frame or a time column) or "
                 "--exif (the frames' own GPS and gimbal tags), one of them");
    }
    if (c.telemetry.fov_deg <= 0.0 && c.telemetry.camera_file.empty()) {
      c.telemetry.fov_deg = c.load.fov_deg;
    }
    c.telemetry.grey = c.load.grey;
    c.telemetry.altitude_window = 0;  // one frame at a time: no running median across frames
    flags.At("telemetry.").NamingFlags([&] { c.telemetry.Check(); });
    // The log as it is now: a header or row it cannot use fails the run before any frame
    // waits for it (later reads may meet a log being rewritten: its frames wait then).
    const bool timed = c.telemetry.frame_interval_s != 0.0 || c.telemetry.time_offset_s != 0.0;
    if (!c.telemetry.telemetry_file.empty() && fs::exists(c.telemetry.telemetry_file)) {
      const LiveLog log = ReadLiveLog(c.telemetry.telemetry_file);
      if (log.time_column >= 0 && c.telemetry.frame_interval_s <= 0.0) {
        ThrowUsage(c.telemetry.telemetry_file + ": a time column (no frame column): give "
                   "--frame-interval-s (seconds between frames; frame i is at "
                   "--time-offset-s + i * --frame-interval-s)");
      }
      if (log.frame_column >= 0 && timed) {
        Warn("--frame-interval-s, --time-offset-s are ignored: " + c.telemetry.telemetry_file +
             " names each frame's row");
      }
    } else if (c.exif && timed) {
      Warn("--frame-interval-s, --time-offset-s are ignored with --exif");
    }
    const fs::path staging = MakePrivateTempFolder("aos-live-", "live");
    struct Cleanup {
      fs::path path;
      ~Cleanup() {
        std::error_code error;
        fs::remove_all(path, error);
      }
    } cleanup{staging};
    std::map<std::string, Watched> watched;
    int next_index = 0;  // the next frame's place in the flight (Watched::index)
    LiveLogReader log_reader(c.telemetry.telemetry_file);
    // --idle-exit-s counts from the last frame that arrived or was integrated; before the
    // first frame it does not count (the run waits for the flight).
    double last_activity_s = -1.0;
    Vec3d origin{0.0};
    std::string crs;
    // A restart: the frames already in the folder are its backlog. Only the newest window of
    // them is integrated (what the live image shows); the earlier ones are passed over.
    {
      std::vector<std::string> present;
      std::error_code error;
      for (const auto& entry : fs::directory_iterator(c.source, error)) {
        if (entry.is_regular_file(error) && FrameName(entry.path())) {
          present.push_back(entry.path().filename().string());
        }
      }
      std::sort(present.begin(), present.end(), NaturalLess);
      for (const std::string& name : present) watched[name].index = next_index++;
      if (!present.empty()) last_activity_s = 0.0;
      const size_t keep = static_cast<size_t>(c.live.window_frames);
      if (present.size() > keep) {
        const size_t skip = present.size() - keep;
        for (size_t k = 0; k < skip; ++k) watched[present[k]].done = true;
        backlog = static_cast<int>(skip);
        if (!Common().quiet && !Common().json) {
          std::fprintf(stderr, "live: %zu frames already in %s: the newest %zu integrated, the "
                       "earlier %zu passed over%s\n", present.size(), c.source.c_str(), keep,
                       skip, c.resume ? " (their tracks come from --resume)" : "");
        }
      }
    }
    // Linux tells when a file's writer closed it or a file was renamed into the folder: such a
    // frame is complete at once. Without inotify (or for files it did not report) a frame is
    // complete once its size and time stayed the same over two polls.
    const int notify = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (notify >= 0 && ::inotify_add_watch(notify, c.source.c_str(), IN_CLOSE_WRITE | IN_MOVED_TO) < 0) {
      ::close(notify);
    }
    struct CloseNotify {
      int fd;
      ~CloseNotify() {
        if (fd >= 0) ::close(fd);
      }
    } close_notify{notify};
    std::set<std::string> closed;  // names inotify reported complete, not yet taken
    while (!Interrupted()) {
      const double now = seconds();
      if (close_notify.fd >= 0) {
        alignas(inotify_event) char buffer[16384];
        for (;;) {
          const ssize_t n = ::read(close_notify.fd, buffer, sizeof(buffer));
          if (n <= 0) break;
          for (ssize_t at = 0; at < n;) {
            const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
            if (event->len > 0) closed.insert(event->name);
            at += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
          }
        }
      }
      std::vector<std::string> ready, arrived;
      std::error_code error;
      for (const auto& entry : fs::directory_iterator(c.source, error)) {
        if (!entry.is_regular_file(error) || !FrameName(entry.path())) continue;
        const std::string name = entry.path().filename().string();
        Watched& w = watched[name];
        if (w.index < 0) arrived.push_back(name);
        if (w.done) continue;
        const uintmax_t size = entry.file_size(error);
        const fs::file_time_type mtime = entry.last_write_time(error);
        if (w.failed && size == w.size && mtime == w.mtime) continue;  // unchanged since
        w.failed = false;
        if (w.first_seen_s == 0.0) {
          w.first_seen_s = now;
          w.seen_unix = UnixSeconds();
        }
        if (size > 0 && size == w.size && mtime == w.mtime) {
          ++w.stable_polls;
        } else {
          w.stable_polls = 0;
        }
        w.size = size;
        w.mtime = mtime;
        const bool reported = closed.erase(name) > 0 && size > 0;
        if (w.stable_polls >= 2 || reported) ready.push_back(name);
      }
      std::sort(arrived.begin(), arrived.end(), NaturalLess);
      for (const std::string& name : arrived) watched[name].index = next_index++;
      if (!arrived.empty()) last_activity_s = now;
      std::sort(ready.begin(), ready.end(), NaturalLess);
      if (!ready.empty()) {
        // Pose frames: a folder of links to them and the log's rows for them (the log,
        // re-read each time, may lag the frames), ImportTelemetry's input: the rows that name
        // them, or (a log with a time column only) the rows around each frame's time,
        // time_offset_s + index * frame_interval_s, as `poses` places frame i of such a log.
        // Frames the log has no row for yet wait, up to 10 s; then they are skipped.
        const LiveLog* log = nullptr;
        std::string log_problem;  // why the log could not be read (it may be being rewritten)
        const auto frame_time = [&](const std::string& name) {
          return c.telemetry.time_offset_s + watched[name].index * c.telemetry.frame_interval_s;
        };
        if (!c.telemetry.telemetry_file.empty()) {
          try {
            log = &log_reader.Read();
          } catch (const std::exception& problem) {
            log_problem = problem.what();
          }
          if (log && log->time_column >= 0 && c.telemetry.frame_interval_s <= 0.0) {
            ThrowUsage(c.telemetry.telemetry_file + ": a time column (no frame column): give "
                       "--frame-interval-s (seconds between frames; frame i is at "
                       "--time-offset-s + i * --frame-interval-s)");
          }
          std::set<std::string> logged;
          if (log && log->frame_column >= 0) LogRowsNaming(*log, ready, &logged);
          std::vector<std::string> posable;
          for (const std::string& name : ready) {
            Watched& w = watched[name];
            bool before_start = false;
            if (log && log->time_column >= 0 &&
                !LogRowsAround(*log, frame_time(name), &before_start).empty()) {
              logged.insert(name);
            }
            if (logged.count(name) > 0) {
              posable.push_back(name);
            } else if (before_start) {
              Warn("live: " + name + ": skipped: its time " + FormatNumber(frame_time(name)) +
                   " s precedes the first row of " + c.telemetry.telemetry_file +
                   " (--time-offset-s, --frame-interval-s)");
              w.done = true;
              ++skipped;
            } else if (now - w.first_seen_s > 10.0) {
              Warn("live: " + name + ": skipped: no row for it in " +
                   c.telemetry.telemetry_file +
                   (log && log->time_column >= 0
                        ? " reaches its time " + FormatNumber(frame_time(name)) + " s"
                        : std::string()) +
                   " within 10 s" + (log_problem.empty() ? "" : " (" + log_problem + ")"));
              w.done = true;
              ++skipped;
            }
          }
          ready = std::move(posable);
        }
        const auto import_frames = [&](const std::vector<std::string>& names) {
          try {
            for (const auto& entry : fs::directory_iterator(staging)) fs::remove_all(entry.path());
            fs::create_directories(staging / "frames");
            for (const std::string& name : names) {
              fs::create_symlink(fs::absolute(fs::path(c.source) / name), staging / "frames" / name);
            }
          } catch (const fs::filesystem_error& error) {
            ThrowInvalid(std::string("live: ") + error.what());
          }
          TelemetryOptions telemetry = c.telemetry;
          if (log) {
            telemetry.telemetry_file = (staging / "log.csv").string();
            std::string rows;
            if (log->frame_column >= 0) {
              std::set<std::string> logged;
              rows = LogRowsNaming(*log, names, &logged);
            } else {  // one frame at a time: it is frame 0, at its own time
              bool before_start = false;
              rows = LogRowsAround(*log, frame_time(names.at(0)), &before_start);
              telemetry.time_offset_s = frame_time(names.at(0));
              telemetry.frame_interval_s = 1.0;
            }
            WriteTextFileAtomic(telemetry.telemetry_file, rows);
          }
          return ImportTelemetry((staging / "frames").string(), telemetry, nullptr);
        };
        std::vector<TelemetryResult> batches;
        // All frames at once (a log by name, or tags); by time, or when one frame's problem (a
        // corrupt header) spoils the batch: each frame alone, and one that fails alone is
        // skipped with one warning (taken again if the file changes).
        bool each_alone = log && log->time_column >= 0;
        if (!each_alone && !ready.empty()) {
          try {
            batches.push_back(import_frames(ready));
          } catch (const std::invalid_argument&) {
            each_alone = true;
          }
        }
        if (each_alone) {
          for (const std::string& name : ready) {
            try {
              batches.push_back(import_frames({name}));
            } catch (const std::invalid_argument& problem) {
              Warn("live: " + name + ": skipped: " + problem.what());
              ++skipped;
              watched[name].failed = true;
            }
          }
        }
        // Frames the import left out (no GPS or gimbal tags yet: a file still being tagged)
        // wait up to 10 s too.
        std::set<std::string> posed_names;
        for (const TelemetryResult& posed : batches) {
          for (const View& view : posed.light_field.views) {
            posed_names.insert(fs::path(view.image_path).filename().string());
          }
        }
        for (const std::string& name : ready) {
          Watched& w = watched[name];
          if (posed_names.count(name) == 0 && !w.failed && now - w.first_seen_s > 10.0) {
            Warn("live: " + name + ": skipped: no telemetry for it within 10 s");
            w.done = true;
            ++skipped;
          }
        }
        for (const TelemetryResult& posed : batches) {
          if (crs.empty() && !posed.light_field.views.empty()) {
            crs = posed.light_field.crs;
            origin = posed.light_field.origin;
            LightField base = EmptyLike(posed.light_field);
            integrator = make_integrator(base);
            // The earlier run's tracks in this run's frame (its origin may differ: local =
            // world - origin), and only in the same CRS.
            if (!resumed.empty() && resumed_crs != crs) {
              ThrowInvalid(c.geojson + ": --resume: crs: its tracks are in '" + resumed_crs +
                           "', this flight in '" + crs + "'");
            }
            for (LiveTrack& track : resumed) track.detection.local = track.detection.world - origin;
            integrator->SeedTracks(resumed);
          }
          if (!posed.light_field.views.empty() && posed.light_field.crs != crs) {
            ThrowInvalid(c.source + ": frames in " + posed.light_field.crs +
                         ", the flight began in " + crs +
                         " (a UTM zone boundary): restart the live run");
          }
          for (const View& posed_view : posed.light_field.views) {
            View view = posed_view;
            const std::string name = fs::path(view.image_path).filename().string();
            Watched& w = watched[name];
            w.done = true;
            // This batch's local frame -> the flight's (world = origin + local): a point's
            // batch coordinates are its flight coordinates + origin - origin_batch, so
            // t' = t + R (origin - origin_batch).
            view.cam_from_world.translation +=
                view.cam_from_world.rotation * (origin - posed.light_field.origin);
            view.image_path = (fs::path(c.source) / name).string();
            view.name = name;
            LightField one = EmptyLike(posed.light_field);
            one.origin = origin;
            one.views.push_back(view);
            try {
              LoadViewImages(one, {0}, c.load);
            } catch (const std::invalid_argument& problem) {
              // Truncated or corrupt: skipped with one warning; taken again only if the file
              // changes (a writer that stalled, then finished).
              Warn("live: " + name + ": skipped: " + problem.what());
              ++skipped;
              w.done = false;
              w.failed = true;
              continue;
            }
            try {
              add(std::move(one.views[0]), w.seen_unix, w.first_seen_s);
            } catch (const std::exception& problem) {
              // A frame the window cannot take (another size or channel count; a render or a
              // detection that fails on it): skipped with one warning, the run goes on.
              Warn("live: " + name + ": skipped: " + problem.what());
              ++skipped;
              continue;
            }
            last_activity_s = seconds();
          }
        }
      }
      if (c.idle_exit_s > 0.0 && last_activity_s >= 0.0 &&
          seconds() - last_activity_s > c.idle_exit_s) {
        // Not while a frame waits for its telemetry (at most 10 s, then it is skipped).
        bool waiting = false;
        for (const auto& [name, w] : watched) waiting = waiting || (!w.done && !w.failed);
        if (!waiting) break;
      }
      if (close_notify.fd >= 0) {  // woken at once by a frame's close or rename
        pollfd wait{close_notify.fd, POLLIN, 0};
        ::poll(&wait, 1, static_cast<int>(c.poll_s * 1000.0));
      } else {
        std::this_thread::sleep_for(std::chrono::duration<double>(c.poll_s));
      }
    }
  }
  const bool interrupted = Interrupted();  // during the run (not while the page stays up)
  if (page && !interrupted) {
    if (!Common().quiet && !Common().json) {
      std::fprintf(stderr, "live: the run ended; the page shows its last update (Ctrl-C stops it)\n");
    }
    while (!Interrupted() && page->Running()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  page.reset();
  Report report("live");
  report.Set("frames", frames);
  report.Set("skipped", skipped);
  report.Set("passed_over", backlog);
  report.Set("updates", integrator ? integrator->updates() : 0);
  report.Set("tracks", integrator ? integrator->tracks().size() : size_t{0});
  report.Set("update_ms_p50", Percentile(update_ms, 0.5));
  report.Set("update_ms_p95", Percentile(update_ms, 0.95));
  report.Set("stopped", interrupted ? std::string("interrupted") : std::string("done"));
  report.Line("%d frames integrated (%d skipped), %zu tracks; update p50 %.1f ms, p95 %.1f ms%s",
              frames, skipped, integrator ? integrator->tracks().size() : size_t{0},
              Percentile(update_ms, 0.5), Percentile(update_ms, 0.95),
              interrupted ? " (interrupted: outputs are those of the last update)" : "");
  if (integrator) {
    int i = 0;
    for (const LiveTrack& track : integrator->tracks()) {
      const Detection& d = track.detection;
      report.Line("%d: world %s %s %s, peak %s, %d sightings (%s .. %s)", ++i,
                  FormatNumber(d.world.x).c_str(), FormatNumber(d.world.y).c_str(),
                  FormatNumber(d.world.z).c_str(), FormatNumber(d.peak_score).c_str(),
                  track.sightings, track.first_frame.c_str(), track.last_frame.c_str());
    }
  }
  report.Print();
  return interrupted ? InterruptExitCode() : 0;
}

}  // namespace

CommandRunner DefineLive(CLI::App* command) {
  auto c = std::make_shared<LiveCommand>();
  Flags flags(command);
  command->add_option("frames_dir", c->source,
                      "Folder to watch: each frame is taken once complete (its size and time "
                      "unchanged over two polls), posed from --telemetry-file or its own tags");
  command->add_option("--replay", c->replay,
                      "Feed a recorded light field's views in order, as if in flight");
  flags.Input("--replay");
  command->add_option("--fps", c->fps, "Replay: frames per second; 0 = as fast as it runs")
      ->default_str("0");
  command->add_option("--idle-exit-s", c->idle_exit_s,
                      "Folder: stop after this many seconds without a new frame (counted once "
                      "the first has come, and not while one waits for its telemetry); 0 = run "
                      "until Ctrl-C")
      ->default_str("0");
  AddLoadFlags(flags, c->load);
  auto* pose = flags.Field(
      c->options, "cam_from_world", [c](const std::string& text) { c->args.cam_from_world = text; },
      " On the command line 12 numbers: the 3x4 matrix [R|t] row by row (--follow fixed).");
  (void)pose;
  flags.Field(c->options, "fov_deg");
  flags.Field(c->options, "width");
  flags.Field(c->options, "height");
  flags.Field(c->options, "aperture_radius");
  flags.Field(c->options, "min_view_angle_deg");
  flags.Field(c->options, "lens_tolerance_px");
  flags.Threads(c->options);
  CLI::Option* surface = AddSurfaceFlags(flags, c->args, c->options);
  AddFocalHeightFlag(flags, c->options.focal_surface,
                     "The horizontal focal plane z = H (local frame, metres); sets --focal-surface")
      ->excludes(surface);
  Flags live = flags.At("live.");
  live.Remaining(c->live);
  Flags mapping = flags.At("map.");
  mapping.Field(c->map, "extent")->expected(4);
  mapping.Field(c->map, "pixel_size");
  Flags telemetry = flags.At("telemetry.");
  telemetry.Field(c->telemetry, "telemetry_file");
  telemetry.Input("--telemetry-file");
  telemetry.Field(c->telemetry, "camera_file");
  telemetry.Input("--camera-file");
  // The frames' camera and grey come from --frames-fov-deg and --grey; one frame at a time has
  // no running altitude median and (so far) no radiometric conversion.
  telemetry.Remaining(c->telemetry,
                      {"fov_deg", "grey", "altitude_window", "max_altitude_deviation_m",
                       "radiometric", "kelvin_per_count", "kelvin_offset",
                       "temperature_frames_dir"});
  command->add_option("--geojson", c->geojson,
                      "The tracks (places found over the flight) as GeoJSON, rewritten "
                      "atomically after every update");
  command->add_option("--csv", c->csv, "The tracks as CSV, rewritten atomically after every update");
  command->add_option("--image", c->image,
                      "The newest integral with its detections boxed (8-bit), rewritten after "
                      "every update");
  for (const char* output : {"--geojson", "--csv", "--image"}) flags.Output(output);
  command->add_flag("--exif", c->exif,
                    "Folder: pose each frame from its own EXIF GPS and DJI XMP gimbal tags (instead "
                    "of --telemetry-file)");
  command->add_flag("--resume", c->resume,
                    "Folder: carry on after a restart: the tracks of --geojson are read back and "
                    "extended (the outputs are rewritten), and of the frames already in the "
                    "folder only the newest window is integrated");
  command->add_flag("--view", c->view,
                    "Serve the live page (the newest integral, detections, tracks, flight path) "
                    "while the run goes on, and after it until Ctrl-C");
  AddViewerFlags(flags, c->viewer, c->no_browser);
  Flags viewer = flags.At("viewer.");
  AddDetectFlags(flags, c->detect);
  flags.Remaining(c->options, {"variance", "pose_view", "view_indices", "min_view_count"});
  viewer.Remaining(c->viewer, {"render_workers"});
  return [c, flags] { return RunLive(*c, flags); };
}

}  // namespace aos::cli
