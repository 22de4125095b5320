#include "aos/live/live.h"

#include <algorithm>
#include <cmath>

#include "aos/util/error.h"

namespace aos {

void LiveOptions::Check() const { CheckFieldRanges(*this); }

LiveIntegrator::LiveIntegrator(const LightField& base, const IntegralOptions& render,
                               const DetectOptions& detect, const LiveOptions& live)
    : render_(render), detect_(detect), live_(live), window_(EmptyLike(base)) {
  live_.Check();
  if (live_.detect) detect_.Check();
  if (!render_.view_indices.empty()) {
    ThrowInvalid("view_indices: live integration takes every view of its window (give "
                 "window_frames instead)");
  }
  if (live_.follow == "fixed" && render_.pose_view >= 0) {
    ThrowInvalid("pose_view: follow 'fixed' takes the options' cam_from_world; pose_view " +
                 std::to_string(render_.pose_view) + " names a view of a window that moves");
  }
  window_.views.clear();
}

IntegralOptions LiveIntegrator::RenderOptions() const {
  IntegralOptions options = render_;
  if (live_.follow == "latest") {
    options.pose_view = window_.views.empty() ? -1 : static_cast<int>(window_.views.size()) - 1;
  }
  return options;
}

std::vector<std::string> LiveIntegrator::Add(View view, bool update, ProgressSink* progress) {
  if (view.image.empty()) ThrowInvalid("view '" + view.name + "': image: not loaded");
  if (!window_.views.empty()) {
    const LensCamera& first = window_.views.front().camera;
    if (view.camera.width != first.width || view.camera.height != first.height) {
      ThrowInvalid("view '" + view.name + "': camera: " + std::to_string(view.camera.width) +
                   " x " + std::to_string(view.camera.height) + " pixels, the window's views are " +
                   std::to_string(first.width) + " x " + std::to_string(first.height));
    }
  }
  for (const View& held : window_.views) {
    if (held.name == view.name) {
      ThrowInvalid("view '" + view.name + "': name: already in the window");
    }
  }
  window_.views.push_back(std::move(view));
  std::vector<std::string> dropped;
  while (window_.views.size() > static_cast<size_t>(live_.window_frames)) {
    dropped.push_back(window_.views.front().name);
    window_.views.erase(window_.views.begin());
  }
  if (update) Update(progress);
  return dropped;
}

bool LiveIntegrator::Remove(const std::string& name, bool update, ProgressSink* progress) {
  const auto it = std::find_if(window_.views.begin(), window_.views.end(),
                               [&](const View& v) { return v.name == name; });
  if (it == window_.views.end()) return false;
  window_.views.erase(it);
  if (update) Update(progress);
  return true;
}

void LiveIntegrator::Update(ProgressSink* progress) {
  ++updates_;
  if (window_.views.empty()) {
    result_ = DetectResult();
    return;
  }
  const IntegralOptions options = RenderOptions();
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
  for (const Detection& d : found.detections) {
    if (!std::isfinite(d.local.x)) continue;  // not on the focal surface: no place to track
    LiveTrack* nearest = nullptr;
    double best = live_.merge_radius_m;
    for (LiveTrack& track : tracks_) {
      const double distance = std::hypot(track.detection.local.x - d.local.x,
                                         track.detection.local.y - d.local.y);
      if (distance <= best) {
        best = distance;
        nearest = &track;
      }
    }
    if (nearest == nullptr) {
      LiveTrack track;
      track.detection = d;
      track.first_update = updates_;
      track.first_frame = newest;
      tracks_.push_back(std::move(track));
      nearest = &tracks_.back();
    } else if (d.peak_score > nearest->detection.peak_score) {
      nearest->detection = d;
    }
    ++nearest->sightings;
    nearest->last_update = updates_;
    nearest->last_frame = newest;
  }
  std::stable_sort(tracks_.begin(), tracks_.end(), [](const LiveTrack& a, const LiveTrack& b) {
    return a.detection.peak_score > b.detection.peak_score;
  });
  if (tracks_.size() > static_cast<size_t>(live_.max_tracks)) {
    tracks_.resize(static_cast<size_t>(live_.max_tracks));
  }
}

DetectResult LiveIntegrator::TracksResult() const {
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
