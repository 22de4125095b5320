#pragma once
// Anomaly scores of an image: the Reed-Xiaoli (RX) detectors, and a plain temperature for
// radiometric images. The scores are what detect.h thresholds into detections.
//
// Contract
// - Features. A pixel's feature vector x (d numbers) comes from its channels by
//   AnomalyOptions::channels: "auto" = the channels as they are (grey or thermal: 1; RGB: 3; RGB +
//   thermal: 4); "grey" = Rec. 601 luminance of the first three (0.299 R + 0.587 G + 0.114 B);
//   "rgb" = the first three; "hsv" = OpenCV's HSV of the first three as (S cos H, S sin H, V),
//   S and V in [0, 1] of the image's range, H in degrees: hue enters through the chroma vector so
//   that red at 359 and 1 degrees is one colour (hue alone wraps around); "rgb+thermal" = the
//   first four channels (a thermal channel beside RGB). Only pixels with a view (count > 0, where
//   a count is given) and finite features take part; the others score 0.
// - Global RX ("rx"): score(x) = (x - m)^T (C + l I)^-1 (x - m), the squared Mahalanobis
//   distance to the background mean m and covariance C of the image, l = regularization *
//   trace(C) / d (+ a floor of 1e-12 of the features' squared scale, so that a constant image
//   scores 0 everywhere, with no NaN). For a Gaussian background a pixel's score is chi-square
//   with d degrees of freedom (what false_alarm_rate's threshold uses, detect.h).
//   Robust background: with trim_fraction t > 0, the estimate is refined by concentration steps
//   (those of the minimum covariance determinant estimator): m and C are recomputed from the
//   (1 - t) share of the pixels with the smallest scores, robust_iterations times, so that a
//   target (a few per cent of the pixels at most) does not inflate the covariance that is to
//   find it. The trimmed covariance is then scaled to be consistent for a Gaussian (divided by
//   P(chi2_{d+2} <= q) / (1 - t), q the (1 - t) quantile of chi2_d); a last reweighting step (as
//   FastMCD's) re-estimates m and C from the pixels within the 97.5 % quantile of chi2_d under
//   that estimate, with the same correction for 2.5 %, so that the estimate does not depend on
//   how far the contamination falls short of t, and scores stay chi-square.
//   With t = 0 this is the classical RX of the whole image: Spectral Python's spectral.rx times
//   N / (N - 1) (it divides the covariance by N - 1, aos by N).
//   Images of more than 65,536 pixels take m and C from the pixels on a regular grid of at
//   most that many (relative error about sqrt(2 / 65536) = 0.6 % per element); every pixel is
//   scored.
// - Dual-window local RX ("rx-local"): m and C per pixel from the pixels of the square outer
//   window (side outer_window_px) outside the square inner guard window (side inner_window_px)
//   centred on it, both clipped to the image; the same regularization of the local trace, plus a
//   millionth of the global trace / d, so flat windows stay invertible. The sums are of the
//   features minus the global mean (large uncentred values keep their digits). At least a quarter
//   of the nominal ring (outer^2 - inner^2 pixels), and 2 d + 1, are needed, else the global
//   estimate stands in (a window clipped by the border or by uncovered pixels).
// - "anomaly-imaging" is global RX here (ComputeAnomalyScores scores one image); detect.h runs
//   it on every frame and integrates the per-frame scores on the focal surface.
// - one_sided (rx and anomaly-imaging, one feature): a pixel below the background mean scores 0,
//   one above it as RX scores it: warm spots in thermal, where cold ground between the crowns
//   would otherwise score as much as a person. The chi-square false-alarm rate then holds for
//   the upper tail (half the two-sided rate).
// - "temperature": the score is the pixel's temperature in degrees Celsius (one channel, and the
//   image's radiometry given), for a plain threshold in physical units.
// - Throws std::invalid_argument naming the field: an image without any pixel that takes part,
//   a channel count the choice cannot use (rgb/hsv/grey need >= 3 channels, rgb+thermal 4,
//   temperature 1 with a radiometry), options out of range.
#include <optional>
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/image/radiometry.h"
#include "aos/render/integral.h"
#include "aos/util/option_fields.h"

namespace aos {

struct AnomalyOptions {
  // "rx" (global), "rx-local" (dual window; the best in docs/detection.md's study, so the
  // default), "anomaly-imaging" (global RX on every frame, the scores integrated like the
  // frames: detect.h) or "temperature" (degrees Celsius; radiometric).
  std::string detector = "rx-local";
  // Features: "auto", "grey", "rgb", "hsv" or "rgb+thermal" (see above).
  std::string channels = "auto";
  // Share of the pixels (those scoring highest) left out of the robust background, [0, 0.5).
  double trim_fraction = 0.05;
  // Concentration steps of the robust background, 0 .. 20.
  int robust_iterations = 3;
  // Ridge added to the covariance, relative to its mean eigenvalue (trace / d), >= 0.
  double regularization = 1e-3;
  // rx-local: the guard window's side (the target), pixels, odd >= 1.
  int inner_window_px = 9;
  // rx-local: the background window's side, pixels, odd, > inner_window_px.
  int outer_window_px = 31;
  // One feature only (grey or thermal), detectors rx and anomaly-imaging: only values above the
  // background mean score (warm spots in thermal); lower values score 0.
  bool one_sided = false;
  void Check() const;

  template <class Visit>
  static void Fields(Visit&& field) {
    using O = AnomalyOptions;
    field(OptionField("detector", &O::detector, "",
                      Range::OneOf("rx|rx-local|anomaly-imaging|temperature"),
                      "Scores: 'rx' (global Reed-Xiaoli), 'rx-local' (dual window, the default), "
                      "'anomaly-imaging' (RX per frame, integrated) or 'temperature' (degrees C, "
                      "radiometric light fields)."));
    field(OptionField("channels", &O::channels, "", Range::OneOf("auto|grey|rgb|hsv|rgb+thermal"),
                      "Features: 'auto' (all channels), 'grey', 'rgb', 'hsv' (S cos H, S sin H, "
                      "V) or 'rgb+thermal' (4 channels)."));
    field(OptionField("trim_fraction", &O::trim_fraction, "", Range::ClosedOpen(0.0, 0.5),
                      "Share of the highest-scoring pixels left out of the robust background; 0 "
                      "= classical RX."));
    field(OptionField("robust_iterations", &O::robust_iterations, "", Range::Closed(0, 20),
                      "Concentration steps of the robust background estimate."));
    field(OptionField("regularization", &O::regularization, "", Range::FiniteAtLeast(0.0),
                      "Ridge added to the covariance, relative to trace / d (keeps flat or "
                      "rank-deficient images invertible)."));
    field(OptionField("inner_window_px", &O::inner_window_px, "px", Range::AtLeast(1),
                      "rx-local: side of the inner guard window, pixels, odd."));
    field(OptionField("outer_window_px", &O::outer_window_px, "px", Range::AtLeast(3),
                      "rx-local: side of the background window, pixels, odd, > "
                      "inner_window_px."));
    field(OptionField("one_sided", &O::one_sided, "", Range::Any(),
                      "rx and anomaly-imaging of one feature (grey or thermal): only values "
                      "above the background mean score (warm spots); lower ones score 0."));
  }
};

struct AnomalyScores {
  Image scores;               // float32, 1 channel, the image's size; 0 where no pixel takes part
  int dimensions = 0;         // d, the features per pixel
  std::vector<double> mean;   // the global (robust) background mean, d
  std::vector<double> covariance;  // its covariance, d x d row-major (regularised as used)
  int64_t pixels = 0;         // pixels that take part
};

// Scores of `image` (float32, as renders give it; any channel count 1..8). `count` (uint32, the
// image's size, or empty = every pixel) marks the pixels with a view. `radiometry` is needed by
// "temperature". `num_threads` (-1 = all cores) runs local RX's rows.
AnomalyScores ComputeAnomalyScores(const Image& image, const Image& count,
                                   const AnomalyOptions& options,
                                   const std::optional<Radiometry>& radiometry = std::nullopt,
                                   int num_threads = -1);

// d, the features per pixel the options take from an image of `image_channels` channels.
int AnomalyFeatureCount(const AnomalyOptions& options, int image_channels);

// Anomaly imaging's per-frame scores: global RX of one frame (options.detector is ignored; "rx"
// is used), quantised to uint16 in steps of kFrameScoreStep (a score s becomes
// min(65535, round(s / kFrameScoreStep)): scores above 2047.97, a 45-sigma outlier of one
// channel, saturate; the mean over frames then errs by at most half a step, 0.016, far below any
// threshold). One channel, one feature and integer frames (8 or 16 bit, the usual thermal frames)
// take the background statistics from a histogram of the sample grid's values and score by a
// table: the same estimate as ComputeAnomalyScores (ties between two values of equal score aside)
// at a fraction of its cost. Other frames are scored by ComputeAnomalyScores. The result has
// the frame's size and border 1 (FillBorder), ready to be integrated as a view's image.
inline constexpr double kFrameScoreStep = 1.0 / 32.0;
Image QuantisedFrameScores(const Image& frame, const AnomalyOptions& options);

// Anomaly imaging's per-frame scores as a quadratic of the frame's value, for one channel, one
// feature ("auto") and integer frames (8 or 16 bit): global RX's background from the histogram
// of the sample grid (as QuantisedFrameScores), its score scale * (value - centre)^2 with
// centre = the background mean and scale = its inverse variance (regularised), one_sided as
// options.one_sided; nullopt for
// other frames. Integrated by RenderIntegralWithQuadratic (integral.h) without a score image,
// and without QuantisedFrameScores' quantisation or saturation.
std::optional<ViewQuadratic> FrameQuadratic(const Image& frame, const AnomalyOptions& options);

// The (1 - p) quantile of the chi-square distribution with `dof` degrees of freedom: the score a
// Gaussian background exceeds with probability p.
double ChiSquareQuantile(int dof, double p_exceed);

}  // namespace aos
