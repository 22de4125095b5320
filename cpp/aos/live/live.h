#pragma once
// Live, in-flight integration: a sliding window of the newest frames, re-rendered and searched
// after each frame joins, and the places found kept over the whole flight.
//
// Contract
// - The window holds at most LiveOptions::window_frames views, in the order they were added;
//   adding a view beyond that drops the oldest, and every view whose centre lies farther than
//   window_m (horizontally) from the newest one's leaves too, and every view whose time (given to
//   Add: seconds, capture or arrival; NaN = none) is more than window_s before the newest's.
//   Remove() takes a view out by name.
//   A view whose update fails (an error from the render or the detector) is not kept: the
//   window is as it was, and the error is thrown.
// - Update() renders the window exactly as the batch renderer renders a light field of those
//   views (RenderIntegral, or Detect when detecting: the same function on the same views, so
//   the live image equals the batch render of the window with the same options, bit for bit).
//   follow "latest": the virtual camera is the newest view's (IntegralOptions::pose_view is set
//   to it; fov_deg, width and height as given); "fixed": the options' own virtual camera
//   (cam_from_world, pose_view -1); "map": the orthographic map (RenderMap / DetectOnMap) of the
//   MapOptions given, whose extent must be set (the map's grid stays the same all flight: pixels
//   the window does not see are uncovered, and an update whose window sees no pixel of it fails
//   like any other, leaving the window as it was).
// - Tracks: each update's detections that are located on the focal surface join the track
//   whose point lies within merge_radius_m (the nearest; horizontal distance in the local
//   frame), else start a new one. A track keeps its strongest sighting (the highest peak score),
//   how many updates saw it and the newest frame's name at its first and last sighting. Tracks
//   are ordered by sightings, then peak score (what persists over the windows is what is there:
//   on F0 the three warm spots are the three most sighted tracks, docs/live.md). At most
//   max_tracks are kept (the first in that order), so a long flight stays bounded.
// - Memory: the window's views (their images shared, not copied), one render and the flight path
//   (every added view's centre, halved in density whenever it reaches kMaxPathPoints); bounded by
//   the window whatever the flight's length.
// - Threads: every member function may be called from several threads (one mutex: an update
//   and a reader such as the viewer's page wait for each other); the accessors return copies
//   (images share their pixels, which an update never changes in place).
// - StateJson(): the newest update as one JSON object, what the live page shows: update,
//   newest frame, window names, the image's size, this update's detections (pixel centroid,
//   area, peak), the tracks (world, local, lon/lat, peak, sightings, first/last frame), the
//   flight path and the window's centres (local x, y), the crs.
// - Throws std::invalid_argument naming the field: a view whose camera size, channel count or
//   pixel type differs from the window's, a repeated name while that view is in the window, options out of range (an
//   IntegralOptions with view_indices: the window is the selection; follow "fixed" with a
//   pose_view).
#include <cmath>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "aos/detect/detect.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/integral.h"
#include "aos/render/map.h"
#include "aos/util/option_fields.h"
#include "aos/util/progress.h"

namespace aos {

struct LiveOptions {
  // The window: the newest frames integrated, >= 1.
  int window_frames = 30;
  // A distance window as well: views whose centre lies farther than this (horizontally, light
  // field units: metres) from the newest view's are dropped, > 0; infinity = none.
  double window_m = std::numeric_limits<double>::infinity();
  // A time window as well: views added more than this many seconds before the newest (by the
  // times given to Add: capture or arrival) are dropped, > 0; infinity = none.
  double window_s = std::numeric_limits<double>::infinity();
  // The virtual camera: "latest" (the newest view's pose), "fixed" (the render options') or
  // "map" (the orthographic map of a fixed area: the MapOptions constructor, its extent given).
  std::string follow = "latest";
  // Run the detector (DetectOptions) on every update.
  bool detect = true;
  // Detections closer than this (horizontally, metres in the light field's units) are one
  // track, > 0.
  double merge_radius_m = 1.5;
  // At most this many tracks are kept (the most sighted), >= 1.
  int max_tracks = 1000;
  void Check() const;

  template <class Visit>
  static void Fields(Visit&& field) {
    using O = LiveOptions;
    field(OptionField("window_frames", &O::window_frames, "", Range::AtLeast(1),
                      "Live: the newest frames integrated (the sliding window)."));
    field(OptionField("window_m", &O::window_m, "m", Range::Above(0.0),
                      "Live: views farther than this from the newest view (horizontally, metres) "
                      "leave the window too; inf = no distance window."));
    field(OptionField("window_s", &O::window_s, "s", Range::Above(0.0),
                      "Live: views taken more than this many seconds before the newest leave the "
                      "window too; inf = no time window."));
    field(OptionField("follow", &O::follow, "", Range::OneOf("latest|fixed|map"),
                      "Live: the virtual camera follows the 'latest' view, stays 'fixed' "
                      "(--cam-from-world / the options' pose), or is the orthographic 'map' of a "
                      "fixed area (--extent)."));
    field(OptionField("detect", &O::detect, "", Range::Any(),
                      "Live: run the detector on every update (true by default; --detect=false integrates only)."));
    field(OptionField("merge_radius_m", &O::merge_radius_m, "m", Range::FiniteAtLeast(0.0, true),
                      "Live: detections closer than this, metres, are one track."));
    field(OptionField("max_tracks", &O::max_tracks, "", Range::AtLeast(1),
                      "Live: at most this many tracks are kept (the most sighted)."));
  }
};

// One place found during the flight.
struct LiveTrack {
  Detection detection;      // its strongest sighting (views: indices into that update's window)
  int sightings = 0;        // updates that detected it (once per update)
  int first_update = 0;     // Update() counts from 1
  int last_update = 0;
  std::string first_frame;  // the newest frame's name at the first and last sighting
  std::string last_frame;
};

class LiveIntegrator {
 public:
  // `base` gives what every view shares (crs, origin, radiometry, grey; its views are ignored).
  LiveIntegrator(const LightField& base, const IntegralOptions& render,
                 const DetectOptions& detect, const LiveOptions& live);
  // follow "map": the window's orthographic map over `map`'s extent (set; no view_indices).
  LiveIntegrator(const LightField& base, const MapOptions& map, const DetectOptions& detect,
                 const LiveOptions& live);

  // Adds a view (image loaded, border 1: MakeView), dropping the oldest beyond the window;
  // returns the names dropped. With `update`, renders and detects (Update()).
  std::vector<std::string> Add(View view, bool update = true, ProgressSink* progress = nullptr,
                               double time_s = std::nan(""));
  // Takes the named view out of the window; false when it is not there.
  bool Remove(const std::string& name, bool update = true, ProgressSink* progress = nullptr);
  // Renders the window and (detect) finds and tracks. An empty window clears the image.
  void Update(ProgressSink* progress = nullptr);

  LightField window() const;
  // The newest update's render and detections (detect: result.detections; else only render).
  DetectResult result() const;
  std::vector<LiveTrack> tracks() const;
  int updates() const;
  // Tracks found before (a resumed run: read back from its GeoJSON), kept as found tracks.
  void SeedTracks(std::vector<LiveTrack> tracks);
  // Every added view's centre (local frame), oldest first (thinned beyond kMaxPathPoints).
  std::vector<Vec3d> path() const;
  // The newest update as JSON (see the contract).
  std::string StateJson() const;
  static constexpr size_t kMaxPathPoints = 10000;
  // The render options the newest update used (pose_view resolved for follow "latest").
  IntegralOptions RenderOptions() const;
  // The tracks as a DetectResult (one detection per track, most sighted first) for
  // WriteDetections.
  DetectResult TracksResult() const;

  const IntegralOptions& render_options() const { return render_; }
  const DetectOptions& detect_options() const { return detect_; }
  const LiveOptions& live_options() const { return live_; }

 private:
  void Track(const DetectResult& found);
  void UpdateLocked(ProgressSink* progress);
  IntegralOptions RenderOptionsLocked() const;
  DetectResult TracksResultLocked() const;

  mutable std::mutex mutex_;
  std::vector<Vec3d> path_;
  std::vector<double> times_;  // the window's views' times (NaN = none), in step with its views

  IntegralOptions render_;
  std::optional<MapOptions> map_;  // follow "map"
  DetectOptions detect_;
  LiveOptions live_;
  LightField window_;
  DetectResult result_;
  std::vector<LiveTrack> tracks_;
  int updates_ = 0;
};

}  // namespace aos
