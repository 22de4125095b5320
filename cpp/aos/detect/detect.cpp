#include "aos/detect/detect.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/geometry/geodesy.h"
#include "aos/render/focal_surface.h"
#include "aos/render/map.h"
#include "aos/util/csv.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/parallel.h"

namespace aos {
namespace {

namespace fs = std::filesystem;

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// A number for the CSV: 15 significant digits (1e-8 m at UTM northings, 1e-13 degrees), "" for
// NaN.
std::string Number(double value) {
  if (!std::isfinite(value)) return "";
  char text[64];
  std::snprintf(text, sizeof(text), "%.15g", value);
  return text;
}

bool Located(const Detection& d) { return std::isfinite(d.local.x); }

std::string GeoJson(const DetectResult& result) {
  nlohmann::ordered_json root;
  root["type"] = "FeatureCollection";
  nlohmann::ordered_json features = nlohmann::ordered_json::array();
  for (size_t i = 0; i < result.detections.size(); ++i) {
    const Detection& d = result.detections[i];
    nlohmann::ordered_json feature;
    feature["type"] = "Feature";
    feature["id"] = static_cast<int>(i + 1);
    if (d.lon_lat) {
      // Longitude, latitude only: RFC 7946's third value is the height above the WGS84
      // ellipsoid, which the CRS's height (properties.world) is not.
      feature["geometry"] = {{"type", "Point"}, {"coordinates", {d.lon_lat->x, d.lon_lat->y}}};
    } else {
      feature["geometry"] = nullptr;
    }
    nlohmann::ordered_json p;
    p["pixel_x"] = d.pixel.x;
    p["pixel_y"] = d.pixel.y;
    p["area_px"] = d.area_px;
    p["peak_score"] = d.peak_score;
    p["mean_score"] = d.mean_score;
    if (Located(d)) {
      p["world"] = {d.world.x, d.world.y, d.world.z};
      p["local"] = {d.local.x, d.local.y, d.local.z};
    } else {
      p["world"] = nullptr;
      p["local"] = nullptr;
    }
    p["crs"] = result.crs;
    p["views"] = d.views;
    if (std::isfinite(d.peak_celsius)) {
      p["peak_celsius"] = d.peak_celsius;
      p["mean_celsius"] = d.mean_celsius;
    }
    if (d.sightings > 0) {
      p["sightings"] = d.sightings;
      p["first_seen"] = d.first_seen;
      p["last_seen"] = d.last_seen;
    }
    feature["properties"] = p;
    features.push_back(feature);
  }
  root["features"] = features;
  root["aos"] = {{"threshold", result.threshold},
                 {"threshold_rule", result.threshold_rule},
                 {"flagged_pixels", result.flagged_pixels},
                 {"dropped", result.dropped},
                 {"crs", result.crs}};
  return root.dump(1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
}

std::string Kml(const DetectResult& result) {
  std::string text =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n<name>aos detections</name>\n";
  for (size_t i = 0; i < result.detections.size(); ++i) {
    const Detection& d = result.detections[i];
    if (!d.lon_lat) continue;
    char line[512];
    std::snprintf(line, sizeof(line),
                  "<Placemark><name>%zu</name><description>peak score %s, %d px, seen by %zu "
                  "views%s</description><Point><coordinates>%.9f,%.9f,%.3f</coordinates></Point>"
                  "</Placemark>\n",
                  i + 1, FormatNumber(d.peak_score).c_str(), d.area_px, d.views.size(),
                  std::isfinite(d.peak_celsius)
                      ? (", peak " + FormatNumber(d.peak_celsius) + " C").c_str()
                      : "",
                  d.lon_lat->x, d.lon_lat->y, d.world.z);
    text += line;
  }
  text += "</Document>\n</kml>\n";
  return text;
}

std::string Csv(const DetectResult& result) {
  std::string text =
      "id,pixel_x,pixel_y,area_px,peak_score,mean_score,world_x,world_y,world_z,lon,lat,crs,views,"
      "peak_celsius,mean_celsius\n";
  for (size_t i = 0; i < result.detections.size(); ++i) {
    const Detection& d = result.detections[i];
    std::string views;
    for (int v : d.views) views += (views.empty() ? "" : " ") + std::to_string(v);
    text += std::to_string(i + 1) + "," + Number(d.pixel.x) + "," + Number(d.pixel.y) + "," +
            std::to_string(d.area_px) + "," + Number(d.peak_score) + "," + Number(d.mean_score) +
            "," + Number(d.world.x) + "," + Number(d.world.y) + "," + Number(d.world.z) + "," +
            (d.lon_lat ? Number(d.lon_lat->x) : "") + "," + (d.lon_lat ? Number(d.lon_lat->y) : "") +
            "," + CsvField(result.crs) + "," + CsvField(views) + "," + Number(d.peak_celsius) + "," +
            Number(d.mean_celsius) + "\n";
  }
  return text;
}

// Synthetic aperture anomaly imaging: global RX on every selected frame, the score images
// integrated on the focal surface like the frames.
AnomalyScores AnomalyImaging(const LightField& light_field, std::vector<int> selected,
                             int num_threads,
                             const std::function<Image(const LightField&)>& render_scores,
                             const DetectOptions& detect, ProgressSink* progress) {
  if (light_field.masked) {
    ThrowInvalid("detector: 'anomaly-imaging' does not take a masked light field (its frames "
                 "carry a weight channel); load it without the mask");
  }
  if (selected.empty()) {
    for (size_t i = 0; i < light_field.views.size(); ++i) selected.push_back(static_cast<int>(i));
  }
  AnomalyOptions per_frame = detect;
  per_frame.detector = "rx";
  // The selected frames' scores as a light field of their own (the same cameras and poses); the
  // camera is resolved already (WithResolvedCamera), so the render takes all of its views.
  LightField scores_field = EmptyLike(light_field);
  scores_field.radiometry.reset();
  scores_field.views.resize(selected.size());
  ProgressStart(progress, "frame scores", static_cast<int64_t>(selected.size()));
  const int dimensions = AnomalyFeatureCount(
      per_frame, light_field.views[static_cast<size_t>(selected[0])].image.channels());
  ParallelFor(static_cast<int64_t>(selected.size()), num_threads, progress,
              [&](int64_t k) {
                const View& view = light_field.views[static_cast<size_t>(selected[static_cast<size_t>(k)])];
                View& scored = scores_field.views[static_cast<size_t>(k)];
                scored.name = view.name;
                scored.camera = view.camera;
                scored.cam_from_world = view.cam_from_world;
                scored.image = QuantisedFrameScores(view.image, per_frame);
              });
  if (ProgressCancelled(progress)) throw Cancelled();
  // The integrated scores: the mean of the frames' (quantised) scores where a view sees the
  // pixel, back in score units.
  AnomalyScores result;
  result.dimensions = dimensions;
  const Image integrated = render_scores(scores_field);
  result.scores = Image(integrated.width(), integrated.height(), 1, PixelType::kF32);
  const float step = static_cast<float>(kFrameScoreStep);
  for (int y = 0; y < integrated.height(); ++y) {
    const float* in = integrated.At<float>(0, y);
    float* row = result.scores.At<float>(0, y);
    for (int x = 0; x < integrated.width(); ++x) row[x] = in[x] * step;
  }
  return result;
}

// Anomaly imaging's per-frame scores as quadratics of the frames' values (FrameQuadratic), one per
// view of the light field (the selected ones set); empty where a selected frame's scores are not
// one (more than one channel or feature, float frames): AnomalyImaging then scores the frames.
std::vector<ViewQuadratic> FrameQuadratics(const LightField& light_field,
                                           std::vector<int> selected, int num_threads,
                                           const DetectOptions& detect, ProgressSink* progress) {
  if (selected.empty()) {
    for (size_t i = 0; i < light_field.views.size(); ++i) selected.push_back(static_cast<int>(i));
  }
  for (int index : selected) {
    const Image& frame = light_field.views[static_cast<size_t>(index)].image;
    if (frame.channels() != 1 || detect.channels != "auto" ||
        (frame.type() != PixelType::kU8 && frame.type() != PixelType::kU16)) {
      return {};
    }
  }
  AnomalyOptions per_frame = detect;
  per_frame.detector = "rx";
  std::vector<ViewQuadratic> quadratics(light_field.views.size());
  std::vector<uint8_t> found(selected.size(), 0);
  ProgressStart(progress, "frame scores", static_cast<int64_t>(selected.size()));
  ParallelFor(static_cast<int64_t>(selected.size()), num_threads, progress, [&](int64_t k) {
    const size_t index = static_cast<size_t>(selected[static_cast<size_t>(k)]);
    if (const auto quadratic = FrameQuadratic(light_field.views[index].image, per_frame)) {
      quadratics[index] = *quadratic;
      found[static_cast<size_t>(k)] = 1;
    }
  });
  if (ProgressCancelled(progress)) throw Cancelled();
  for (uint8_t one : found) {
    if (!one) return {};
  }
  return quadratics;
}

}  // namespace

void DetectOptions::Check() const {
  AnomalyOptions::Check();
  CheckFieldRanges(*this);
  if (false_alarm_rate && !(*false_alarm_rate > 0.0 && *false_alarm_rate < 1.0)) {
    ThrowInvalid("false_alarm_rate: must be in (0, 1), got " + FormatNumber(*false_alarm_rate));
  }
  if (min_score && !(*min_score >= 0.0 && std::isfinite(*min_score))) {
    ThrowInvalid("min_score: must be a finite score >= 0, got " + FormatNumber(*min_score));
  }
  if (quantile && !(*quantile > 0.0 && *quantile < 1.0)) {
    ThrowInvalid("quantile: must be in (0, 1), got " + FormatNumber(*quantile));
  }
  if (robust_sigmas && !(*robust_sigmas > 0.0 && std::isfinite(*robust_sigmas))) {
    ThrowInvalid("robust_sigmas: must be a finite number > 0, got " + FormatNumber(*robust_sigmas));
  }
  {
    std::vector<std::string> rules;
    if (min_score) rules.push_back("min_score");
    if (false_alarm_rate) rules.push_back("false_alarm_rate");
    if (quantile) rules.push_back("quantile");
    if (robust_sigmas) rules.push_back("robust_sigmas");
    if (rules.size() > 1) {
      ThrowInvalid("min_score, false_alarm_rate, quantile, robust_sigmas: give one threshold "
                   "rule, not " + rules[0] + " and " + rules[1]);
    }
  }
  if (false_alarm_rate && detector == "anomaly-imaging") {
    ThrowInvalid("false_alarm_rate: anomaly-imaging's scores are means over frames, not "
                 "chi-square: give robust_sigmas, quantile or min_score");
  }
  if (!(outer_window_m > inner_window_m)) {
    ThrowInvalid("outer_window_m: must be larger than inner_window_m (" +
                 FormatNumber(inner_window_m) + "), got " + FormatNumber(outer_window_m));
  }
  if (detector == "temperature") {
    if (!min_temperature_c) {
      ThrowInvalid("min_temperature_c: detector 'temperature' needs the temperature a pixel must "
                   "exceed, degrees C");
    }
    if (!std::isfinite(*min_temperature_c) || *min_temperature_c < -273.15) {
      ThrowInvalid("min_temperature_c: must be a finite temperature above absolute zero, got " +
                   FormatNumber(*min_temperature_c));
    }
    if (false_alarm_rate || min_score || quantile || robust_sigmas) {
      ThrowInvalid(std::string(false_alarm_rate ? "false_alarm_rate"
                               : min_score      ? "min_score"
                               : quantile       ? "quantile"
                                                : "robust_sigmas") +
                   ": detector 'temperature' is thresholded by min_temperature_c");
    }
  } else if (min_temperature_c) {
    ThrowInvalid("min_temperature_c: applies to detector 'temperature' only (it is '" + detector +
                 "')");
  }
}

double ResolveThreshold(const AnomalyScores& scores, const Image& count,
                        const DetectOptions& options, std::string* rule) {
  if (options.detector == "temperature") {
    *rule = "min_temperature_c " + FormatNumber(*options.min_temperature_c);
    return *options.min_temperature_c;
  }
  if (options.min_score) {
    *rule = "min_score " + FormatNumber(*options.min_score);
    return *options.min_score;
  }
  const bool imaging = options.detector == "anomaly-imaging";
  if (options.false_alarm_rate || (!options.quantile && !options.robust_sigmas && !imaging)) {
    const double rate = options.false_alarm_rate.value_or(kDefaultFalseAlarmRate);
    *rule = "false_alarm_rate " + FormatNumber(rate) + " (chi-square, " +
            std::to_string(scores.dimensions) + " degrees of freedom)";
    return ChiSquareQuantile(scores.dimensions, rate);
  }
  std::vector<float> values;
  for (int y = 0; y < scores.scores.height(); ++y) {
    for (int x = 0; x < scores.scores.width(); ++x) {
      if (!count.empty() && *count.At<uint32_t>(x, y) == 0) continue;
      values.push_back(*scores.scores.At<float>(x, y));
    }
  }
  if (values.empty()) ThrowInvalid("image: no pixel with a view: nothing to threshold");
  // Anomaly imaging without a rule: quantile 0.998, one-sided robust_sigmas 13.5 (the study's
  // choice: one-sided scores leave a quiet background whose spread sets the threshold; two-sided
  // ones in dense canopy have tails a spread underestimates, so the quantile bounds them).
  std::string fallback;  // robust_sigmas without a spread: why the quantile rule stands in
  if (options.robust_sigmas || (!options.quantile && options.one_sided)) {
    const double sigmas = options.robust_sigmas.value_or(kDefaultRobustSigmas);
    // The median (the mean of the middle two for an even count).
    const auto median_of = [](std::vector<float>& v) {
      const size_t half = v.size() / 2;
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(half), v.end());
      double median = v[half];
      if (v.size() % 2 == 0) {
        median = 0.5 * (median + *std::max_element(v.begin(),
                                                   v.begin() + static_cast<std::ptrdiff_t>(half)));
      }
      return median;
    };
    std::vector<float> deviations = values;
    const double median = median_of(deviations);
    for (float& v : deviations) v = static_cast<float>(std::abs(v - median));
    const double mad = median_of(deviations);
    // The statistics to 3 significant digits: the rule is read by people (the threshold
    // itself is reported in full).
    char statistics[96];
    std::snprintf(statistics, sizeof statistics, " (median %.3g, MAD %.3g)", median, mad);
    *rule = "robust_sigmas " + FormatNumber(sigmas) + statistics;
    if (mad > 0.0) return median + sigmas * 1.4826 * mad;
    // More than half the scores are equal (one-sided scores of a cold, quiet scene are mostly
    // 0): no spread to scale, and a threshold at the median would flag everything above it.
    fallback = *rule + ": no spread, so quantile " + FormatNumber(kDefaultQuantile) + " instead";
  }
  const double quantile = options.quantile.value_or(kDefaultQuantile);
  const size_t k = std::min(values.size() - 1,
                            static_cast<size_t>(std::floor(quantile *
                                                           static_cast<double>(values.size() - 1))));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  *rule = fallback.empty() ? "quantile " + FormatNumber(quantile) : fallback;
  return values[k];
}

namespace {

// The blobs (as FindBlobs) with the label image and each blob's label, for LocateBlobs to take
// a blob's own pixels (bounding boxes of 8-connected components overlap). Components under
// min_area_px are left out before any Detection is made, so a noisy image costs no more than
// its pixels.
struct Blobs {
  std::vector<Detection> detections;  // highest peak first
  std::vector<int> labels;            // the component label of each
  cv::Mat label_image;                // CV_32S, 0 = not flagged
};

Blobs LabelBlobs(const Image& scores, const Image& count, double threshold, int min_area_px) {
  const int w = scores.width(), h = scores.height();
  cv::Mat mask(h, w, CV_8U, cv::Scalar(0));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float s = *scores.At<float>(x, y);
      if (s > threshold && (count.empty() || *count.At<uint32_t>(x, y) > 0)) {
        mask.at<uint8_t>(y, x) = 1;
      }
    }
  }
  Blobs blobs;
  cv::Mat stats, centroids;
  const int n =
      cv::connectedComponentsWithStats(mask, blobs.label_image, stats, centroids, 8, CV_32S);
  std::vector<int> slot(static_cast<size_t>(std::max(n, 1)), -1);  // label -> index, or -1
  for (int label = 1; label < n; ++label) {
    if (stats.at<int>(label, cv::CC_STAT_AREA) < min_area_px) continue;
    slot[static_cast<size_t>(label)] = static_cast<int>(blobs.detections.size());
    Detection d;
    d.box = {stats.at<int>(label, cv::CC_STAT_LEFT), stats.at<int>(label, cv::CC_STAT_TOP),
             stats.at<int>(label, cv::CC_STAT_LEFT) + stats.at<int>(label, cv::CC_STAT_WIDTH),
             stats.at<int>(label, cv::CC_STAT_TOP) + stats.at<int>(label, cv::CC_STAT_HEIGHT)};
    d.peak_score = -std::numeric_limits<double>::infinity();
    blobs.detections.push_back(d);
    blobs.labels.push_back(label);
  }
  std::vector<double> weight(blobs.detections.size(), 0.0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int label = blobs.label_image.at<int>(y, x);
      if (label == 0 || slot[static_cast<size_t>(label)] < 0) continue;
      const size_t k = static_cast<size_t>(slot[static_cast<size_t>(label)]);
      Detection& d = blobs.detections[k];
      const double s = *scores.At<float>(x, y);
      // Weights above the threshold, so that every flagged pixel counts (scores may be negative:
      // temperatures).
      const double wgt = s - threshold;
      d.pixel += wgt * Vec2d(x + 0.5, y + 0.5);
      weight[k] += wgt;
      d.mean_score += s;
      ++d.area_px;
      d.peak_score = std::max(d.peak_score, s);
    }
  }
  for (size_t k = 0; k < blobs.detections.size(); ++k) {
    Detection& d = blobs.detections[k];
    d.pixel /= weight[k];
    d.mean_score /= d.area_px;
  }
  std::vector<size_t> order(blobs.detections.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return blobs.detections[a].peak_score > blobs.detections[b].peak_score;
  });
  Blobs sorted;
  sorted.label_image = blobs.label_image;
  for (size_t k : order) {
    sorted.detections.push_back(blobs.detections[k]);
    sorted.labels.push_back(blobs.labels[k]);
  }
  return sorted;
}

}  // namespace

std::vector<Detection> FindBlobs(const Image& scores, const Image& count, double threshold,
                                 int min_area_px) {
  return LabelBlobs(scores, count, threshold, min_area_px).detections;
}

namespace {

// rx-local's windows from metres on the ground, by the render's ground sampling distance.
DetectOptions ScoringOptions(const DetectOptions& options, double ground_sampling_m,
                             std::array<int, 2>* windows_px) {
  DetectOptions scoring = options;
  if (scoring.detector == "rx-local" && ground_sampling_m > 0.0) {
    const auto odd_pixels = [&](double metres, int at_least) {
      const int pixels =
          static_cast<int>(std::lround(std::min(metres / ground_sampling_m, 1e6)));
      return std::max(at_least, pixels | 1);
    };
    scoring.inner_window_px = odd_pixels(scoring.inner_window_m, 1);
    scoring.outer_window_px = std::max(odd_pixels(scoring.outer_window_m, 3),
                                       scoring.inner_window_px + 2);
  }
  *windows_px = {scoring.inner_window_px, scoring.outer_window_px};
  return scoring;
}

// The threshold, the flagged pixels and the blobs of result->scores (on result->render).
Blobs ThresholdAndBlobs(const DetectOptions& options, DetectResult* result) {
  const Image& count = result->render.count;
  result->threshold = ResolveThreshold(result->scores, count, options, &result->threshold_rule);
  for (int y = 0; y < count.height(); ++y) {
    for (int x = 0; x < count.width(); ++x) {
      if (*count.At<uint32_t>(x, y) > 0 &&
          *result->scores.scores.At<float>(x, y) > result->threshold) {
        ++result->flagged_pixels;
      }
    }
  }
  Blobs blobs = LabelBlobs(result->scores.scores, count, result->threshold, options.min_area_px);
  if (blobs.detections.size() > static_cast<size_t>(options.max_detections)) {
    result->dropped = static_cast<int>(blobs.detections.size()) - options.max_detections;
    blobs.detections.resize(static_cast<size_t>(options.max_detections));
    blobs.labels.resize(static_cast<size_t>(options.max_detections));
  }
  return blobs;
}

// Each blob's place (the score-weighted mean of its flagged pixels' points, `point_of` giving a
// pixel's point in the local frame, or nothing), temperatures, views and WGS84 position.
void LocateBlobs(const LightField& light_field, std::vector<int> selected,
                 const std::function<std::optional<Vec3d>(int, int)>& point_of,
                 Blobs found, DetectResult* result) {
  std::vector<Detection>& blobs = found.detections;
  const Image& image = result->render.image;
  if (selected.empty()) {
    for (size_t i = 0; i < light_field.views.size(); ++i) selected.push_back(static_cast<int>(i));
  }
  const bool temperatures = light_field.radiometry && image.channels() == 1;
  std::vector<Vec3d> world_points;
  for (size_t k = 0; k < blobs.size(); ++k) {
    Detection& d = blobs[k];
    const int label = found.labels[k];
    Vec3d sum(0.0);
    double total = 0.0, celsius_sum = 0.0;
    double celsius_peak = -std::numeric_limits<double>::infinity();
    for (int y = d.box[1]; y < d.box[3]; ++y) {
      for (int x = d.box[0]; x < d.box[2]; ++x) {
        if (found.label_image.at<int>(y, x) != label) continue;  // this blob's pixels only
        const double s = *result->scores.scores.At<float>(x, y);
        if (temperatures) {
          const double c = light_field.radiometry->Celsius(*image.At<float>(x, y));
          celsius_sum += c;
          celsius_peak = std::max(celsius_peak, c);
        }
        const std::optional<Vec3d> point = point_of(x, y);
        if (!point) continue;
        const double weight = s - result->threshold;
        sum += weight * *point;
        total += weight;
      }
    }
    if (temperatures) {
      d.peak_celsius = celsius_peak;
      d.mean_celsius = celsius_sum / d.area_px;
    }
    if (total > 0.0) {
      d.local = sum / total;
      d.world = light_field.origin + d.local;
      for (int v : selected) {
        const View& view = light_field.views[static_cast<size_t>(v)];
        const Vec3d in_view = view.cam_from_world * d.local;
        Vec2d pixel;
        if (in_view.z > 0.0 && view.camera.Project(in_view, &pixel) && pixel.x >= 0.0 &&
            pixel.y >= 0.0 && pixel.x < view.camera.width && pixel.y < view.camera.height) {
          d.views.push_back(v);
        }
      }
      world_points.push_back(d.world);
    } else {
      d.local = Vec3d(std::nan(""));
      d.world = Vec3d(std::nan(""));
    }
  }
  if (!light_field.crs.empty() && !world_points.empty()) {
    const std::vector<Vec3d> geographic =
        TransformPoints(world_points, light_field.crs, "EPSG:4326", "detections");
    size_t k = 0;
    for (Detection& d : blobs) {
      if (Located(d)) {
        d.lon_lat = Vec2d(geographic[k].x, geographic[k].y);
        ++k;
      }
    }
  }
  result->detections = std::move(blobs);
}

// The checks and fields every detection starts with.
DetectResult StartDetection(const LightField& light_field, const DetectOptions& detect_options) {
  detect_options.Check();
  if (light_field.views.empty()) ThrowInvalid("light field: no views: nothing to detect in");
  // one_sided needs one feature: refused before any render where the frames are loaded (every
  // frame has the first's channels; the renders check that).
  const Image& first = light_field.views.front().image;
  if (detect_options.one_sided && !first.empty()) {
    const int channels = first.channels() - (light_field.masked ? 1 : 0);
    const int features = AnomalyFeatureCount(detect_options, channels);
    if (features != 1) {
      ThrowInvalid("one_sided: needs one feature (grey or thermal), got " +
                   std::to_string(features) + " (channels '" + detect_options.channels + "')");
    }
  }
  DetectResult result;
  result.crs = light_field.crs;
  result.radiometry = light_field.radiometry;
  return result;
}

}  // namespace

DetectResult Detect(const LightField& light_field, const IntegralOptions& options,
                    const DetectOptions& detect_options, ProgressSink* progress) {
  DetectResult result = StartDetection(light_field, detect_options);
  // The options are checked before the camera is resolved and frames are scored (pose_view and
  // view indices in range, each view once).
  options.Check(static_cast<int>(light_field.views.size()));
  const IntegralOptions resolved = WithResolvedCamera(light_field, options);
  // Anomaly imaging whose frames' scores are quadratics of their values (1-channel integer
  // frames) on the homography route: one pass renders the frames and integrates their scores
  // (RenderIntegralWithQuadratic); otherwise the frames' scores are made and rendered apart.
  std::optional<Image> integrated_scores;
  if (detect_options.detector == "anomaly-imaging" &&
      QuadraticIntegralSupported(light_field, resolved)) {
    const std::vector<ViewQuadratic> quadratics = FrameQuadratics(
        light_field, resolved.view_indices, resolved.num_threads, detect_options, progress);
    if (!quadratics.empty()) {
      QuadraticIntegralResult both =
          RenderIntegralWithQuadratic(light_field, resolved, quadratics, progress);
      result.render = std::move(both.integral);
      integrated_scores = std::move(both.scores);
    }
  }
  if (!integrated_scores) result.render = RenderIntegral(light_field, resolved, progress);
  if (ProgressCancelled(progress)) throw Cancelled();
  result.camera = VirtualCamera(light_field, resolved);
  const Image& count = result.render.count;
  // Where each pixel's ray meets the focal surface: the detections' places, and the render's
  // ground sampling distance (rx-local's windows in metres).
  const SurfacePlacement placement = ResolveSurfacePlacement(
      resolved.focal_surface, light_field, resolved.view_indices, resolved.surface_offset);
  const Image depth = resolved.focal_surface.DepthFor(result.camera, result.render.cam_from_world,
                                                      placement, resolved.num_threads);
  {
    std::vector<float> depths;
    for (int y = 0; y < depth.height(); ++y) {
      for (int x = 0; x < depth.width(); ++x) {
        const float z = *depth.At<float>(x, y);
        if (z > 0.0f && *count.At<uint32_t>(x, y) > 0) depths.push_back(z);
      }
    }
    if (!depths.empty()) {
      std::nth_element(depths.begin(), depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2),
                       depths.end());
      result.ground_sampling_m = depths[depths.size() / 2] / result.camera.fx;
    }
  }
  const DetectOptions scoring =
      ScoringOptions(detect_options, result.ground_sampling_m, &result.windows_px);
  if (integrated_scores) {
    result.scores.scores = std::move(*integrated_scores);
    result.scores.dimensions = 1;
  } else if (scoring.detector == "anomaly-imaging") {
    result.scores = AnomalyImaging(light_field, resolved.view_indices, resolved.num_threads,
                                   [&](const LightField& scores_field) {
                                     IntegralOptions all = resolved;
                                     all.view_indices.clear();
                                     return RenderIntegral(scores_field, all, progress).image;
                                   },
                                   scoring, progress);
  } else {
    result.scores =
        ComputeAnomalyScores(result.render.image, count, scoring, light_field.radiometry,
                             resolved.num_threads);
  }
  Blobs blobs = ThresholdAndBlobs(detect_options, &result);
  const Mat3d world_from_cam = glm::transpose(result.render.cam_from_world.rotation);
  const Vec3d centre = result.render.cam_from_world.Center();
  LocateBlobs(
      light_field, resolved.view_indices,
      [&](int x, int y) -> std::optional<Vec3d> {
        const float z = *depth.At<float>(x, y);
        if (!(z > 0.0f)) return std::nullopt;
        const Vec3d in_cam =
            result.camera.Unproject(Vec2d(x + 0.5, y + 0.5)) * static_cast<double>(z);
        return world_from_cam * in_cam + centre;
      },
      std::move(blobs), &result);
  return result;
}

namespace {

// DetectOnMap after its render: `map` is the map of `options`.
// `anomaly_scores`: anomaly imaging's integrated frame scores, rendered elsewhere (else rendered
// here).
DetectResult DetectOnMapOf(const LightField& light_field, const MapOptions& options,
                           const DetectOptions& detect_options, MapResult map,
                           ProgressSink* progress,
                           std::optional<Image> anomaly_scores = std::nullopt) {
  DetectResult result = StartDetection(light_field, detect_options);
  const MapGrid& grid = map.summary.grid;
  result.geotransform = grid.GeoTransform();
  result.render.image = std::move(map.image);
  result.render.count = std::move(map.count);
  result.render.uncovered_pixels = map.summary.uncovered_pixels;
  result.render.views_used = map.summary.views_used;
  result.render.views_selected = map.summary.views_selected;
  result.render.samples = map.summary.samples;
  result.ground_sampling_m = grid.pixel_size;
  const DetectOptions scoring =
      ScoringOptions(detect_options, result.ground_sampling_m, &result.windows_px);
  if (anomaly_scores) {
    result.scores.scores = std::move(*anomaly_scores);
    // The frames' features: the map's channels are theirs (a masked light field is refused).
    result.scores.dimensions = AnomalyFeatureCount(scoring, result.render.image.channels());
  } else if (scoring.detector == "anomaly-imaging") {
    result.scores = AnomalyImaging(light_field, options.view_indices, options.num_threads,
                                   [&](const LightField& scores_field) {
                                     MapOptions all = options;
                                     all.view_indices.clear();
                                     // The same grid: the extent and pixel size resolved above.
                                     all.extent = {grid.x_min, grid.y_max - grid.height * grid.pixel_size,
                                                   grid.x_min + grid.width * grid.pixel_size, grid.y_max};
                                     all.pixel_size = grid.pixel_size;
                                     return RenderMap(scores_field, all, progress).image;
                                   },
                                   scoring, progress);
  } else {
    result.scores =
        ComputeAnomalyScores(result.render.image, result.render.count, scoring,
                             light_field.radiometry, options.num_threads);
  }
  if (result.scores.scores.width() != result.render.image.width() ||
      result.scores.scores.height() != result.render.image.height()) {
    throw std::logic_error("DetectOnMap: the scores' grid differs from the map's");
  }
  Blobs blobs = ThresholdAndBlobs(detect_options, &result);
  // A map pixel's point: its centre's vertical line on the focal surface (or plane).
  LocateBlobs(
      light_field, options.view_indices,
      [&](int x, int y) -> std::optional<Vec3d> {
        const double wx = grid.CenterX(x), wy = grid.CenterY(y);
        double z = grid.origin.z + grid.focal_height;
        if (grid.surface) {
          z = grid.surface->HeightsAt({Vec2d(wx, wy)}, grid.placement).front();
          if (!std::isfinite(z)) return std::nullopt;
        }
        return Vec3d(wx, wy, z) - grid.origin;
      },
      std::move(blobs), &result);
  return result;
}

}  // namespace

DetectResult DetectOnMap(const LightField& light_field, const MapOptions& options,
                         const DetectOptions& detect_options, ProgressSink* progress) {
  StartDetection(light_field, detect_options);  // checks before the render
  MapResult map = RenderMap(light_field, options, progress);
  if (ProgressCancelled(progress)) throw Cancelled();
  return DetectOnMapOf(light_field, options, detect_options, std::move(map), progress);
}

DetectResult DetectOnRenderedMap(const LightField& light_field, const MapOptions& options,
                                 const DetectOptions& detect_options, MapResult map,
                                 std::optional<Image> anomaly_scores) {
  detect_options.Check();
  const bool imaging = detect_options.detector == "anomaly-imaging";
  if (imaging && !anomaly_scores) {
    ThrowInvalid("anomaly_scores: anomaly-imaging needs the frames' scores rendered on the map's "
                 "grid where the map was (none given)");
  }
  if (!imaging && anomaly_scores) {
    ThrowInvalid("anomaly_scores: given, but detector '" + detect_options.detector +
                 "' scores the map itself");
  }
  if (imaging && light_field.masked) {
    ThrowInvalid("detector: 'anomaly-imaging' does not take a masked light field (its frames "
                 "carry a weight channel); load it without the mask");
  }
  map.summary.grid = ResolveMapGrid(light_field, options);
  const MapGrid& grid = map.summary.grid;
  if (map.image.width() != grid.width || map.image.height() != grid.height ||
      map.count.width() != grid.width || map.count.height() != grid.height ||
      map.count.type() != PixelType::kU32 || map.count.channels() != 1 ||
      map.image.type() != PixelType::kF32) {
    ThrowInvalid("map: image (float32) and count (uint32) must be the grid's " +
                 std::to_string(grid.width) + " x " + std::to_string(grid.height) + " pixels, got " +
                 std::to_string(map.image.width()) + " x " + std::to_string(map.image.height()) +
                 " and " + std::to_string(map.count.width()) + " x " +
                 std::to_string(map.count.height()));
  }
  int64_t samples = 0, uncovered = 0;
  for (int y = 0; y < grid.height; ++y) {
    const uint32_t* row = map.count.At<uint32_t>(0, y);
    for (int x = 0; x < grid.width; ++x) {
      samples += row[x];
      uncovered += row[x] == 0;
    }
  }
  if (anomaly_scores &&
      (anomaly_scores->width() != grid.width || anomaly_scores->height() != grid.height ||
       anomaly_scores->type() != PixelType::kF32 || anomaly_scores->channels() != 1)) {
    ThrowInvalid("anomaly_scores: must be float32 of 1 channel and the grid's " +
                 std::to_string(grid.width) + " x " + std::to_string(grid.height) + " pixels, got " +
                 std::to_string(anomaly_scores->width()) + " x " +
                 std::to_string(anomaly_scores->height()) + " x " +
                 std::to_string(anomaly_scores->channels()));
  }
  if (map.summary.samples == 0) map.summary.samples = samples;
  map.summary.uncovered_pixels = uncovered;
  return DetectOnMapOf(light_field, options, detect_options, std::move(map), nullptr,
                       std::move(anomaly_scores));
}

void CheckDetectionsPath(const std::string& path, const std::string& crs) {
  const std::string extension = Lower(fs::path(path).extension().string());
  if (extension != ".geojson" && extension != ".json" && extension != ".kml" &&
      extension != ".csv") {
    ThrowInvalid(path + ": unknown detections format '" + extension +
                 "' (.geojson, .json, .kml or .csv)");
  }
  if (extension == ".kml" && crs.empty()) {
    ThrowInvalid(path + ": KML is in WGS84 longitude and latitude: the light field has no CRS "
                 "(not geo-referenced); write GeoJSON or CSV");
  }
}

void WriteDetections(const std::string& path, const DetectResult& result, bool overwrite) {
  CheckDetectionsPath(path, result.crs);
  const std::string extension = Lower(fs::path(path).extension().string());
  const std::string text = extension == ".kml"   ? Kml(result)
                           : extension == ".csv" ? Csv(result)
                                                 : GeoJson(result);
  std::error_code error;
  if (!overwrite && fs::exists(path, error)) {
    ThrowInvalid(path + ": exists (give overwrite / --force to replace it)");
  }
  WriteTextFileAtomic(path, text);
}

Image DetectionOverlay(const DetectResult& result) {
  const Image& image = result.render.image;
  const Image& count = result.render.count;
  const int w = image.width(), h = image.height();
  const int c = image.channels();
  const bool colour = c >= 3;
  std::vector<float> values;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (*count.At<uint32_t>(x, y) == 0) continue;
      for (int k = 0; k < (colour ? 3 : 1); ++k) values.push_back(image.At<float>(x, y)[k]);
    }
  }
  double low = 0.0, high = 1.0;
  if (!values.empty()) {
    const auto at = [&](double p) {
      const size_t k = static_cast<size_t>(p * static_cast<double>(values.size() - 1));
      std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
      return static_cast<double>(values[k]);
    };
    low = at(0.01);
    high = at(0.99);
    if (!(high > low)) high = low + 1.0;
  }
  cv::Mat canvas(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float* p = image.At<float>(x, y);
      cv::Vec3b& out = canvas.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k) {
        const double v = p[colour ? k : 0];
        out[k] = static_cast<uint8_t>(std::clamp((v - low) / (high - low) * 255.0 + 0.5, 0.0, 255.0));
      }
    }
  }
  const int thickness = std::max(1, std::min(w, h) / 256);
  for (size_t i = 0; i < result.detections.size(); ++i) {
    const Detection& d = result.detections[i];
    const int margin = 2 * thickness;
    const cv::Point corner(std::max(0, d.box[0] - margin), std::max(0, d.box[1] - margin));
    const cv::Point far(std::min(w - 1, d.box[2] - 1 + margin), std::min(h - 1, d.box[3] - 1 + margin));
    cv::rectangle(canvas, corner, far, cv::Scalar(255, 0, 0), thickness);  // RGB order: red
    cv::putText(canvas, std::to_string(i + 1), cv::Point(far.x + 2, std::max(10, corner.y + 10)),
                cv::FONT_HERSHEY_SIMPLEX, 0.4 * thickness, cv::Scalar(255, 0, 0), thickness);
  }
  Image overlay(w, h, 3, PixelType::kU8);
  overlay.CopyFrom(canvas.data, static_cast<ptrdiff_t>(canvas.step1()));
  return overlay;
}

}  // namespace aos
