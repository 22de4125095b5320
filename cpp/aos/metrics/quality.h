#pragma once
// Image quality against a reference: MSE/PSNR, SSIM (Wang et al. 2004) and a colour SSIM in the
// spirit of the AOS paper's quaternion SSIM (Kolaman & Yadid-Pecht 2012). Definitions in
// docs/metrics.md; in short, with data range L, C1 = (k1 L)^2, C2 = (k2 L)^2 and Gaussian-weighted
// local statistics (sigma 1.5 px, 11 x 11 window):
//   PSNR  = 10 log10(L^2 / MSE), MSE over all channels of the compared pixels (+inf if MSE = 0);
//   SSIM  = mean over channels and pixels of (2 mu_a mu_b + C1)(2 s_ab + C2) /
//           ((mu_a^2 + mu_b^2 + C1)(s_a^2 + s_b^2 + C2));
//   colour SSIM: the same with each pixel a pure quaternion r i + g j + b k, products and
//           covariances quaternion-valued and the two factors replaced by their norms; for a
//           one-channel image it equals SSIM.
// Compared pixels: SSIM maps are averaged over pixels whose whole window lies inside the image;
// with a mask (any integer image, e.g. a count map; non-zero = valid) only pixels whose window
// lies entirely in valid pixels count, and MSE/PSNR use the valid pixels.
//
// Sample types: images of the same type are compared as they are. An integer test image of
// another integer type than the reference (8-bit against 16-bit) is normalised by each type's full
// range: its values are multiplied by range(reference) / range(test) (257 for 8 -> 16 bit), and L
// defaults to the reference's range. A float32 image against an integer one is compared in the
// integer image's units (aos writes float renders in the views' units) with L from the integer
// type; when the float image's values all lie in [-1, 1] while the integer one's exceed 1 (a
// normalised float image), the comparison is refused. QualityResult::note says what was done.
//
// Memory and cancellation: the SSIM statistics are computed in bands of rows (a few MiB of
// working planes, CompareImagesWorkingBytes) whatever the image size; that figure is checked
// against the memory budget (util/memory.h) before anything is allocated, and an allocation that
// fails anyway is reported as one std::invalid_argument. The progress sink (may be null) is
// polled every band of rows; when it asks to stop, aos::Cancelled is thrown.
//
// Throws std::invalid_argument for images of different size or channel count (a grey image
// against a colour one: the message names QualityOptions::grey), a mask of another
// size, no pixel to compare, non-finite values, bad options, or too little memory; messages
// start with "compare: " (callers replace it with the files' names).
#include <cstdint>
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct QualityOptions {
  // Peak-to-peak value range L; 0 = from the reference's pixel type (8-bit 255, 16-bit 65535,
  // float 1.0).
  double data_range = 0.0;
  // Standard deviation of the Gaussian window, pixels (> 0).
  double gaussian_sigma = 1.5;
  // Window radius, pixels (>= 1); the window is (2r + 1)^2.
  int window_radius = 5;
  // Stabilising constants of SSIM, (0, 1).
  double k1 = 0.01;
  double k2 = 0.03;
  // Compare luminances: images with 3 or 4 channels become one-channel Rec. 601 luminance
  // (LuminanceImage in image.h) before anything else, so a grey render (LoadOptions::grey) can be
  // scored against an RGB reference. Without it, channel counts must match.
  bool grey = false;
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = QualityOptions;
    field(OptionField("data_range", &O::data_range, "", Range::Any(),
                      "Peak-to-peak value range L; 0 = from the reference's dtype (uint8 255, "
                      "uint16 65535, float 1.0)."));
    field(OptionField("gaussian_sigma", &O::gaussian_sigma, "", Range::Any(),
                      "Standard deviation of the SSIM window, pixels (> 0)."));
    field(OptionField("window_radius", &O::window_radius, "", Range::Any(),
                      "SSIM window radius, pixels (>= 1); the window is (2r + 1)^2.")
              .Flag("ssim-window-radius"));
    field(OptionField("k1", &O::k1, "", Range::Any(),
                      "SSIM constant k1, (0, 1)."));
    field(OptionField("k2", &O::k2, "", Range::Any(),
                      "SSIM constant k2, (0, 1)."));
    field(OptionField("grey", &O::grey, "", Range::Any(),
                      "Compare luminances: 3- or 4-channel images become Rec. 601 luminance "
                      "first."));
  }
};

struct QualityResult {
  double mse = 0.0;
  double psnr_db = 0.0;             // +inf when the images are identical
  double ssim = 0.0;                // mean over channels
  std::vector<double> ssim_channels;
  double color_ssim = 0.0;          // quaternion SSIM (equals ssim for one channel)
  double data_range = 0.0;          // L used
  int64_t mse_pixels = 0;           // pixels in MSE/PSNR
  int64_t ssim_pixels = 0;          // pixels in the SSIM averages
  double test_scale = 1.0;          // factor applied to the test image (mismatched integer types)
  std::string note;                 // how mismatched sample types were reconciled; empty if same
};

QualityResult CompareImages(const Image& test, const Image& reference, const Image* mask = nullptr,
                            const QualityOptions& options = {}, ProgressSink* progress = nullptr);

// Bytes CompareImages allocates besides its inputs for a test image of width x height pixels of
// test_channels x test_type and a reference of reference_channels x reference_type (same size):
// the luminance copies when options.grey converts an image, and the banded working planes. The
// CLI adds the decoded images to it to check a comparison before reading any pixel.
uint64_t CompareImagesWorkingBytes(int width, int height, int test_channels, PixelType test_type,
                                   int reference_channels, PixelType reference_type,
                                   const QualityOptions& options);

}  // namespace aos
