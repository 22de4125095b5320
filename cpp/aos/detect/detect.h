#pragma once
// Finding the person: anomaly scores (anomaly.h) of an integral image thresholded into blobs,
// each located on the focal surface, in the world and (geo-referenced light fields) in WGS84,
// with the views that saw it; written as GeoJSON, KML, CSV and an overlay image.
//
// Contract
// - Scores: detector "rx", "rx-local" and "temperature" score the integral image (anomaly.h).
//   "anomaly-imaging" (synthetic aperture anomaly imaging) scores every selected frame with
//   global RX first (each frame its own background; a lens view's frame as it is), then
//   integrates those score images on the focal surface exactly as the frames are integrated
//   (same virtual camera, surface, aperture and views): a pixel's score is the mean of its
//   frames' scores, an occluder that hides the target in some frames only dilutes it. The
//   integral image of the frames is rendered too (for the overlay and temperatures). Masked
//   light fields are refused for it.
// - Threshold (DetectOptions): detector "temperature" takes min_temperature_c (degrees Celsius,
//   required). Otherwise one of: min_score (an absolute score); false_alarm_rate p (the score a
//   Gaussian background exceeds with probability p per pixel: the chi-square quantile with d
//   degrees of freedom, anomaly.h; not for anomaly-imaging, whose mean scores are no
//   chi-square); quantile q (the research code's convention: the top 1 - q of the scores of the
//   pixels with a view, whatever is in the image); robust_sigmas k (the median of those scores
//   plus k x 1.4826 x their median absolute deviation: k robust standard deviations above the
//   background, scale-free). None given: kDefaultFalseAlarmRate for rx and rx-local;
//   kDefaultQuantile for anomaly-imaging, kDefaultRobustSigmas for it one-sided (chosen by
//   tools/detection_study.py: docs/detection.md). A pixel is flagged when its score is strictly above the threshold and
//   it has a view, so a constant image flags nothing.
// - Blobs: the 8-connected components of the flagged pixels with at least min_area_px pixels;
//   pixel = the score-weighted centroid (continuous coordinates, pixel centres at +0.5), area,
//   peak and mean score, bounding box. At most max_detections are kept (the highest peaks; the
//   rest are counted in `dropped`), so the outputs stay bounded on any image.
// - Location: each flagged pixel's ray meets the focal surface (FocalSurface::DepthFor of the
//   virtual camera); the blob's point is the score-weighted mean of its pixels' points (local
//   frame), world = origin + local; NaN when no pixel of the blob meets the surface. With a CRS,
//   lon_lat is the point in WGS84 (PROJ, EPSG:4326: degrees east, north).
// - Views: the selected views (IntegralOptions' view_indices, all when empty) in whose image the
//   point lies (in front of the camera, inside the frame; a lens view through its lens model).
// - Radiometric light fields (LightField::radiometry, one channel): each blob's peak and mean
//   temperature in degrees Celsius from the integral image.
// - Writers refuse a format they do not know and, for KML, a light field without a CRS (KML is
//   WGS84 only); GeoJSON follows RFC 7946 (WGS84 longitude, latitude: the world height is a
//   property, since RFC 7946's third coordinate is ellipsoidal; a light field without a CRS
//   gives null geometries and the local/world coordinates as properties). CSV fields are quoted
//   per RFC 4180 where needed. Writes are atomic (a temporary file renamed into place).
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "aos/detect/anomaly.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/integral.h"
#include "aos/render/map.h"
#include "aos/util/option_fields.h"
#include "aos/util/progress.h"

namespace aos {

// The threshold rules used when none is given (docs/detection.md: the study that chose them).
inline constexpr double kDefaultFalseAlarmRate = 1e-8;
// anomaly-imaging: quantile 0.998; one-sided, median + 13.5 robust standard deviations (about
// 20 median absolute deviations).
inline constexpr double kDefaultQuantile = 0.998;
inline constexpr double kDefaultRobustSigmas = 13.5;

struct DetectOptions : AnomalyOptions {
  // Threshold at this quantile of the scores, (0, 1): 0.999 flags the top 0.1 % of the pixels;
  // unset = not used.
  std::optional<double> quantile;
  // Per-pixel false-alarm rate of a Gaussian background, (0, 1); unset = not used.
  std::optional<double> false_alarm_rate;
  // An absolute score threshold, >= 0; unset = not used.
  std::optional<double> min_score;
  // Threshold at the covered scores' median plus this many robust standard deviations (1.4826 x
  // their median absolute deviation), > 0; unset = not used.
  std::optional<double> robust_sigmas;
  // detector "temperature": the temperature a pixel must exceed, degrees Celsius.
  std::optional<double> min_temperature_c;
  // rx-local on a render: the guard and background windows on the ground, metres, converted
  // to pixels by the render's ground sampling distance (the median over its pixels of depth / fx
  // on the focal surface); they replace inner_window_px and outer_window_px there (those stay
  // for anomaly_scores on an image). The guard holds a person (1.8 m lying); > 0 each, outer >
  // inner.
  double inner_window_m = 2.5;
  double outer_window_m = 8.0;
  // Blobs smaller than this are dropped, pixels, >= 1.
  int min_area_px = 4;
  // At most this many detections are kept (the highest peaks), >= 1.
  int max_detections = 100;
  void Check() const;

  template <class Visit>
  static void Fields(Visit&& field) {
    using O = DetectOptions;
    AnomalyOptions::Fields(field);
    field(OptionField("quantile", &O::quantile, "", Range::Any(),
                      "Threshold at this quantile of the scores, (0, 1): 0.999 = the top 0.1 % "
                      "of the pixels; unset = not used (no rule given: false_alarm_rate 1e-8; "
                      "anomaly-imaging quantile 0.998, one-sided robust_sigmas 13.5)."));
    field(OptionField("false_alarm_rate", &O::false_alarm_rate, "", Range::Any(),
                      "Threshold: per-pixel false-alarm rate of a Gaussian background, (0, 1) "
                      "(the chi-square quantile); unset = not used."));
    field(OptionField("min_score", &O::min_score, "", Range::Any(),
                      "Threshold: an absolute score (squared Mahalanobis distance), >= 0; unset "
                      "= not used."));
    field(OptionField("robust_sigmas", &O::robust_sigmas, "", Range::Any(),
                      "Threshold: the covered scores' median plus this many robust standard "
                      "deviations (1.4826 x median absolute deviation), > 0; unset = not used."));
    field(OptionField("min_temperature_c", &O::min_temperature_c, "C", Range::Any(),
                      "Detector 'temperature': the temperature a pixel must exceed, degrees C."));
    field(OptionField("inner_window_m", &O::inner_window_m, "m", Range::FiniteAtLeast(0.0, true),
                      "rx-local on a render: guard window on the ground, metres (replaces "
                      "inner_window_px there)."));
    field(OptionField("outer_window_m", &O::outer_window_m, "m", Range::FiniteAtLeast(0.0, true),
                      "rx-local on a render: background window on the ground, metres, > "
                      "inner_window_m."));
    field(OptionField("min_area_px", &O::min_area_px, "px", Range::AtLeast(1),
                      "Blobs smaller than this many pixels are dropped."));
    field(OptionField("max_detections", &O::max_detections, "", Range::AtLeast(1),
                      "At most this many detections (the highest peaks) are kept."));
  }
};

struct Detection {
  Vec2d pixel{0.0};              // score-weighted centroid (pixel centres at +0.5)
  int area_px = 0;
  double peak_score = 0.0;
  double mean_score = 0.0;
  std::array<int, 4> box{0, 0, 0, 0};  // x0, y0, x1, y1 (x1, y1 exclusive)
  Vec3d local{0.0};              // on the focal surface, local frame (NaN when not located)
  Vec3d world{0.0};              // origin + local
  std::optional<Vec2d> lon_lat;  // WGS84 degrees (with a CRS)
  std::vector<int> views;        // the views that saw the point
  double peak_celsius = std::nan("");  // radiometric light fields
  double mean_celsius = std::nan("");
  // Live tracks only (live/live.h): the updates that saw it and the newest frame's name at the
  // first and the last; 0 and empty otherwise (written to GeoJSON when set).
  int sightings = 0;
  std::string first_seen;
  std::string last_seen;
};

struct DetectResult {
  IntegralResult render;          // the integral image the scores were computed on
  PinholeCamera camera;           // its virtual camera
  double ground_sampling_m = 0.0; // the render's metres per pixel on the focal surface (median)
  std::array<int, 2> windows_px{0, 0};  // rx-local's inner and outer windows as used, pixels
  AnomalyScores scores;
  double threshold = 0.0;
  std::string threshold_rule;     // "quantile 0.999", "false_alarm_rate 1e-05", ...
  int64_t flagged_pixels = 0;
  std::vector<Detection> detections;  // highest peak first
  int dropped = 0;                // blobs beyond max_detections
  std::string crs;                // the light field's (lon_lat is WGS84)
  std::optional<Radiometry> radiometry;
  // Detection on the orthographic map (DetectOnMap): its GDAL geotransform (x_min, p, 0, y_max,
  // 0, -p) in the light field's CRS; render.cam_from_world and camera are then unused.
  std::optional<std::array<double, 6>> geotransform;
};

// The threshold of `scores` under `options` (see the contract); `rule` gets its description.
double ResolveThreshold(const AnomalyScores& scores, const Image& count,
                        const DetectOptions& options, std::string* rule);

// The blobs of `scores` above `threshold` where count > 0 (pixel fields only), highest peak
// first.
std::vector<Detection> FindBlobs(const Image& scores, const Image& count, double threshold,
                                 int min_area_px);

// Renders the integral image of `options`, scores it and finds, locates and lists the
// detections. `progress` as RenderIntegral's (and polled for cancellation).
DetectResult Detect(const LightField& light_field, const IntegralOptions& options,
                    const DetectOptions& detect_options, ProgressSink* progress = nullptr);

// As Detect, on the orthographic map of `options` (render/map.h: RenderMap): rx-local's windows
// by the map's pixel size; a detection's point is its pixels' vertical lines on the focal
// surface (MapGrid: the plane or the surface's heights); anomaly imaging renders the frames'
// scores on the same grid.
DetectResult DetectOnMap(const LightField& light_field, const MapOptions& options,
                         const DetectOptions& detect_options, ProgressSink* progress = nullptr);

// As DetectOnMap, on a map rendered elsewhere (a Dask cluster: python/aos/distributed): `map`
// holds the image and count of ResolveMapGrid(light_field, options)'s grid (its summary's
// views_used and samples as reported; the grid is resolved again here and must have the map's
// size). Anomaly imaging needs the integrated frame scores rendered there too,
// `anomaly_scores` (float32, 1 channel, the grid's size: the map of every selected frame's
// QuantisedFrameScores times kFrameScoreStep, as DetectOnMap renders it); they are refused for
// the other detectors, and their absence for anomaly imaging, naming the field. `light_field`
// may hold poses only.
DetectResult DetectOnRenderedMap(const LightField& light_field, const MapOptions& options,
                                 const DetectOptions& detect_options, MapResult map,
                                 std::optional<Image> anomaly_scores = std::nullopt);

// Refuses, before any work, a detections path WriteDetections would refuse: an extension it does
// not write, or KML for a light field without a CRS (`crs` empty). Names `path`.
void CheckDetectionsPath(const std::string& path, const std::string& crs);

// Writes the detections to `path` as GeoJSON (.geojson, .json), KML (.kml) or CSV (.csv).
// `overwrite` false refuses an existing file.
void WriteDetections(const std::string& path, const DetectResult& result, bool overwrite = false);

// The integral image as 8-bit RGB (its 1st..99th percentile stretched over 0..255, colour kept
// where it has three channels) with each detection's box drawn in red and its number beside it.
Image DetectionOverlay(const DetectResult& result);

}  // namespace aos
