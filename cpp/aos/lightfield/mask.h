#pragma once
// Masks: which pixels of a frame hold scene (a letterbox, a logo or a timestamp burnt into
// thermal frames do not), applied when a light field is loaded (LoadOptions::mask, mask_dir in
// formats.h).
//
// Contract
// - A mask is an image file of the frame's size, any pixel type; a pixel is valid where its
//   colour channels are not all zero (1 or 2 channels: channel 0; 3 or 4: R, G, B; alpha is
//   ignored). Soft masks are not supported: any non-zero value is fully valid.
// - A masked frame of C channels (C <= 3) becomes C + 1 channels of the same pixel type:
//   (v_1 m, ..., v_C m, w) with m = 1 on valid pixels and 0 on masked ones, and
//   w = m * full range (255 for 8-bit, 65535 for 16-bit, 4294967295 for 32-bit, 1 for float).
//   Averaging such frames (the renderer's bilinear samples and sums) gives mean(v m) and
//   mean(w); their quotient times the full range is the mean over valid samples alone, which
//   the renderer computes in one place (integral.h: masked light fields). The 8-bit frames stay
//   8-bit: the premultiplied values are exact (v * 1 or 0).
// - Frames of 4 channels (RGBA) cannot take a mask (the renderer takes at most 4 channels):
//   load them with LoadOptions::grey, or drop the alpha.
//
// Errors are std::invalid_argument naming the mask file and, for a size mismatch, both sizes.
#include <string>

#include "aos/image/image.h"

namespace aos {

// The valid pixels of mask file `path`: a 1-channel uint8 image, 1 = valid, 0 = masked, no
// border. Throws naming `path` when the file cannot be read.
Image ReadMask(const std::string& path);

// Number of valid pixels of a mask from ReadMask.
int64_t CountValid(const Image& valid);

// `frame` (C <= 3 channels, border >= 0) with its mask applied as above: C + 1 channels, the
// same pixel type, border 1 (replicated, as views need). Throws std::invalid_argument
// "<where>: ..." when the frame has 4 channels or the sizes differ (naming `mask_path`, its size
// and the frame's).
Image ApplyMask(const Image& frame, const Image& valid, const std::string& mask_path,
                const std::string& where);

}  // namespace aos
