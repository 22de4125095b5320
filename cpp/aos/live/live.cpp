#include "aos/live/live.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "aos/util/error.h"

namespace aos {

void LiveOptions::Check() const { CheckFieldRanges(*this); }

namespace {

// Track order: the most sighted first (a person stays; a false alarm of one window does not),
// then the highest peak.
bool MoreSeen(const LiveTrack& a, const LiveTrack& b) {
  if (a.sightings != b.sightings) return a.sightings > b.sightings;
  return a.detection.peak_score > b.detection.peak_score;
}

}  // namespace

LiveIntegrator::LiveIntegrator(const LightField& base, const IntegralOptions& render,
                               const DetectOptions& detect, const LiveOptions& live)
    : render_(render), detect_(detect), live_(live), window_(EmptyLike(base)) {
  live_.Check();
  if (live_.detect) detect_.Check();
  if (!render_.view_indices.empty()) {
    ThrowInvalid("view_indices: live integration takes every view of its window (give "
                 "window_frames instead)");
  }
  if (live_.follow == "map") {
    ThrowInvalid("follow: 'map' renders the orthographic map of a fixed area: construct with "
                 "MapOptions (its extent set)");
  }
  if (live_.follow == "fixed" && render_.pose_view >= 0) {
    ThrowInvalid("pose_view: follow 'fixed' takes the options' cam_from_world; pose_view " +
                 std::to_string(render_.pose_view) + " names a view of a window that moves");
  }
  window_.views.clear();
}

LiveIntegrator::LiveIntegrator(const LightField& base, const MapOptions& map,
                               const DetectOptions& detect, const LiveOptions& live)
    : map_(map), detect_(detect), live_(live), window_(EmptyLike(base)) {
  live_.Check();
  if (live_.detect) detect_.Check();
  if (live_.follow != "map") {
    ThrowInvalid("follow: '" + live_.follow + "' with MapOptions: give follow 'map' (or "
                 "IntegralOptions for a camera)");
  }
  if (map.extent.empty()) {
    ThrowInvalid("extent: follow 'map' needs the map's area (XMIN, YMIN, XMAX, YMAX, world "
                 "metres): the window's own footprint moves with the flight");
  }
  if (!map.view_indices.empty()) {
    ThrowInvalid("view_indices: live integration takes every view of its window (give "
                 "window_frames instead)");
  }
  window_.views.clear();
}

IntegralOptions LiveIntegrator::RenderOptions() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return RenderOptionsLocked();
}

IntegralOptions LiveIntegrator::RenderOptionsLocked() const {
  IntegralOptions options = render_;
  if (live_.follow == "latest") {
    options.pose_view = window_.views.empty() ? -1 : static_cast<int>(window_.views.size()) - 1;
  }
  return options;
}

std::vector<std::string> LiveIntegrator::Add(View view, bool update, ProgressSink* progress,
                                             double time_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (view.image.empty()) ThrowInvalid("view '" + view.name + "': image: not loaded");
  if (!window_.views.empty()) {
    const LensCamera& first = window_.views.front().camera;
    if (view.camera.width != first.width || view.camera.height != first.height) {
      ThrowInvalid("view '" + view.name + "': camera: " + std::to_string(view.camera.width) +
                   " x " + std::to_string(view.camera.height) + " pixels, the window's views are " +
                   std::to_string(first.width) + " x " + std::to_string(first.height));
    }
    const Image& held = window_.views.front().image;
    if (view.image.channels() != held.channels() || view.image.type() != held.type()) {
      ThrowInvalid("view '" + view.name + "': image: " + std::to_string(view.image.channels()) +
                   " channels of " + PixelTypeName(view.image.type()) + ", the window's are " +
                   std::to_string(held.channels()) + " of " + PixelTypeName(held.type()));
    }
  }
  for (const View& held : window_.views) {
    if (held.name == view.name) {
      ThrowInvalid("view '" + view.name + "': name: already in the window");
    }
  }
  // On an error in the update the window is as it was before (the view is not kept).
  const std::vector<View> before = window_.views;
  const std::vector<double> times_before = times_;
  const Vec3d centre = view.cam_from_world.Center();
  window_.views.push_back(std::move(view));
  times_.push_back(time_s);
  std::vector<std::string> dropped;
  const auto drop = [&](size_t i) {
    dropped.push_back(window_.views[i].name);
    window_.views.erase(window_.views.begin() + static_cast<std::ptrdiff_t>(i));
    times_.erase(times_.begin() + static_cast<std::ptrdiff_t>(i));
  };
  // The distance and time windows: any view too far or too old (NaN times compare false).
  for (size_t i = 0; i + 1 < window_.views.size();) {
    const Vec3d c = window_.views[i].cam_from_world.Center();
    const bool too_far = std::hypot(c.x - centre.x, c.y - centre.y) > live_.window_m;
    const bool too_old = time_s - times_[i] > live_.window_s;
    if (too_far || too_old) {
      drop(i);
    } else {
      ++i;
    }
  }
  while (window_.views.size() > static_cast<size_t>(live_.window_frames)) drop(0);
  if (update) {
    try {
      UpdateLocked(progress);
    } catch (...) {
      window_.views = before;
      times_ = times_before;
      throw;
    }
  }
  path_.push_back(centre);
  if (path_.size() >= kMaxPathPoints) {  // every other point: the shape stays, memory is bounded
    std::vector<Vec3d> thinned;
    for (size_t i = 0; i < path_.size(); i += 2) thinned.push_back(path_[i]);
    thinned.push_back(path_.back());
    path_ = std::move(thinned);
  }
  return dropped;
}

bool LiveIntegrator::Remove(const std::string& name, bool update, ProgressSink* progress) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = std::find_if(window_.views.begin(), window_.views.end(),
                               [&](const View& v) { return v.name == name; });
  if (it == window_.views.end()) return false;
  times_.erase(times_.begin() + (it - window_.views.begin()));
  window_.views.erase(it);
  if (update) UpdateLocked(progress);
  return true;
}

void LiveIntegrator::Update(ProgressSink* progress) {
  std::lock_guard<std::mutex> lock(mutex_);
  UpdateLocked(progress);
}

LightField LiveIntegrator::window() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return window_;
}

DetectResult LiveIntegrator::result() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return result_;
}

std::vector<LiveTrack> LiveIntegrator::tracks() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return tracks_;
}

int LiveIntegrator::updates() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return updates_;
}

void LiveIntegrator::SeedTracks(std::vector<LiveTrack> tracks) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (LiveTrack& track : tracks) tracks_.push_back(std::move(track));
  std::stable_sort(tracks_.begin(), tracks_.end(), MoreSeen);
  if (tracks_.size() > static_cast<size_t>(live_.max_tracks)) {
    tracks_.resize(static_cast<size_t>(live_.max_tracks));
  }
}

std::vector<Vec3d> LiveIntegrator::path() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return path_;
}

void LiveIntegrator::UpdateLocked(ProgressSink* progress) {
  ++updates_;
  if (window_.views.empty()) {
    result_ = DetectResult();
    return;
  }
  if (map_) {
    if (live_.detect) {
      result_ = DetectOnMap(window_, *map_, detect_, progress);
      Track(result_);
    } else {
      MapResult map = RenderMap(window_, *map_, progress);
      DetectResult result;
      result.geotransform = map.summary.grid.GeoTransform();
      result.render.image = std::move(map.image);
      result.render.count = std::move(map.count);
      result.render.uncovered_pixels = map.summary.uncovered_pixels;
      result.render.views_used = map.summary.views_used;
      result.crs = window_.crs;
      result.radiometry = window_.radiometry;
      result_ = std::move(result);
    }
    return;
  }
  const IntegralOptions options = RenderOptionsLocked();
  if (live_.detect) {
    result_ = Detect(window_, options, detect_, progress);
    Track(result_);
  } else {
    DetectResult result;
    result.render = RenderIntegral(window_, options, progress);
    result.crs = window_.crs;
    result.radiometry = window_.radiometry;
    result_ = std::move(result);
  }
}

void LiveIntegrator::Track(const DetectResult& found) {
  const std::string& newest = window_.views.back().name;
  std::vector<size_t> seen;  // tracks already counted in this update (indices: tracks_ grows)
  for (const Detection& d : found.detections) {
    if (!std::isfinite(d.local.x)) continue;  // not on the focal surface: no place to track
    size_t nearest = tracks_.size();
    double best = live_.merge_radius_m;
    for (size_t k = 0; k < tracks_.size(); ++k) {
      const double distance = std::hypot(tracks_[k].detection.local.x - d.local.x,
                                         tracks_[k].detection.local.y - d.local.y);
      if (distance <= best) {
        best = distance;
        nearest = k;
      }
    }
    if (nearest == tracks_.size()) {
      LiveTrack track;
      track.detection = d;
      track.first_update = updates_;
      track.first_frame = newest;
      tracks_.push_back(std::move(track));
    } else if (d.peak_score > tracks_[nearest].detection.peak_score) {
      tracks_[nearest].detection = d;
    }
    LiveTrack& track = tracks_[nearest];
    if (std::find(seen.begin(), seen.end(), nearest) == seen.end()) {  // once per update
      ++track.sightings;
      seen.push_back(nearest);
    }
    track.last_update = updates_;
    track.last_frame = newest;
  }
  std::stable_sort(tracks_.begin(), tracks_.end(), MoreSeen);
  if (tracks_.size() > static_cast<size_t>(live_.max_tracks)) {
    tracks_.resize(static_cast<size_t>(live_.max_tracks));
  }
}

DetectResult LiveIntegrator::TracksResult() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return TracksResultLocked();
}

DetectResult LiveIntegrator::TracksResultLocked() const {
  DetectResult result;
  result.crs = window_.crs;
  result.radiometry = window_.radiometry;
  result.threshold = result_.threshold;
  result.threshold_rule = result_.threshold_rule;
  for (const LiveTrack& track : tracks_) {
    Detection d = track.detection;
    d.sightings = track.sightings;
    d.first_seen = track.first_frame;
    d.last_seen = track.last_frame;
    result.detections.push_back(std::move(d));
  }
  return result;
}

}  // namespace aos

namespace aos {

std::string LiveIntegrator::StateJson() const {
  std::lock_guard<std::mutex> lock(mutex_);
  nlohmann::ordered_json state;
  const auto number = [](double v) -> nlohmann::ordered_json {
    return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
  };
  state["update"] = updates_;
  state["frame"] = window_.views.empty() ? std::string() : window_.views.back().name;
  nlohmann::ordered_json names = nlohmann::ordered_json::array();
  nlohmann::ordered_json window_path = nlohmann::ordered_json::array();
  for (const View& view : window_.views) {
    names.push_back(view.name);
    const Vec3d c = view.cam_from_world.Center();
    window_path.push_back({c.x, c.y});
  }
  state["window"] = names;
  state["window_frames"] = live_.window_frames;
  state["width"] = result_.render.image.width();
  state["height"] = result_.render.image.height();
  state["crs"] = window_.crs;
  state["origin"] = {window_.origin.x, window_.origin.y, window_.origin.z};
  state["threshold_rule"] = result_.threshold_rule;
  nlohmann::ordered_json detections = nlohmann::ordered_json::array();
  for (const Detection& d : result_.detections) {
    detections.push_back({{"x", d.pixel.x}, {"y", d.pixel.y}, {"area_px", d.area_px},
                          {"peak_score", number(d.peak_score)}});
  }
  state["detections"] = detections;
  nlohmann::ordered_json tracks = nlohmann::ordered_json::array();
  for (const LiveTrack& t : tracks_) {
    const Detection& d = t.detection;
    nlohmann::ordered_json track;
    track["world"] = {number(d.world.x), number(d.world.y), number(d.world.z)};
    track["local"] = {number(d.local.x), number(d.local.y), number(d.local.z)};
    track["lon_lat"] = d.lon_lat ? nlohmann::ordered_json({d.lon_lat->x, d.lon_lat->y})
                                 : nlohmann::ordered_json(nullptr);
    track["peak_score"] = number(d.peak_score);
    track["sightings"] = t.sightings;
    track["first_frame"] = t.first_frame;
    track["last_frame"] = t.last_frame;
    tracks.push_back(track);
  }
  state["tracks"] = tracks;
  nlohmann::ordered_json path = nlohmann::ordered_json::array();
  for (const Vec3d& c : path_) path.push_back({c.x, c.y});
  state["path"] = path;
  state["window_path"] = window_path;
  // Frame names that are not UTF-8 (a byte from another encoding) are replaced, not an error.
  return state.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

}  // namespace aos
