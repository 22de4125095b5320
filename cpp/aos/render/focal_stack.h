#pragma once
// Focal stacks: integral images of one virtual camera on N focal planes interpolated between two
// boundary planes (the paper renders 100 between the ground and the canopy top).
//
// Contract
// - Plane interpolation is relative to the virtual camera centre C: a plane is (n, h) with n its
//   unit normal and h = n . (p - C) its signed distance from C. The last plane's (n, h) is
//   negated if its normal points against the first's; slice i of N takes
//   n = normalize((1 - s) n0 + s n1), h = (1 - s) h0 + s h1, s = i / (N - 1) (s = 1/2 when
//   N = 1), and is stored as the plane through C + h n with normal n. Parallel boundary planes
//   give equally spaced parallel slices; identical ones give N identical slices.
// - Terrain-following stacks. With a render.focal_surface that is not a plane (a mesh, DEM or
//   depth map: focal_surface.h; FollowsSurface), slice i lies on that surface moved along up by
//   o_i = first_offset + (last_offset - first_offset) i / (N - 1) (the midway offset when
//   N = 1; the last is last_offset exactly): the same surface N times,
//   N offsets, each slice rendered as RenderIntegral renders a surface (rays that miss it give
//   count 0). first_plane/last_plane are then ignored. render.surface_offset must be 0 in every
//   stack (the offsets or planes replace it); a plane as render.focal_surface other than the
//   default z = 0 is refused (the slices' planes would replace it; ground_plane gives planes
//   parallel to a given one). The surface is placed once for the whole stack
//   (ResolveSurfacePlacement: the views' up, the light field's origin).
// - Stacks around the ground. With ground_plane set (and a plane focal_surface), the boundary planes
//   are ground_plane moved first_offset and last_offset along its normal turned towards the
//   views (the mean centre of the selected views); first_plane/last_plane are then ignored. The
//   ground plane comes from an estimate (sfm/ground.h: EstimateGround's robust plane through
//   COLMAP's points; `aos-render stack --ground points.ply`).
// - Each slice is RenderIntegral's result with FocalStackOptions::render (its focal_surface or
//   surface_offset replaced by the slice's),
//   so every rule of integral.h holds per slice (count 0 where no view sees a pixel).
// - A stack on disk is a folder: stack.json (camera, pose, planes, file names) and per slice
//   slice_NNNN.tif (float32 image), count_NNNN.tif (uint32) and, when rendered with variance,
//   variance_NNNN.tif (float32). WriteFocalStack writes into a hidden temporary folder and renames
//   it into place; it refuses an existing non-empty folder. ReadFocalStack checks every field and
//   file and names them in its errors; FocalStack::Check refuses non-finite pixels and negative
//   variances. stack.json's camera (a pinhole), cam_from_world and slice planes use the shared
//   JSON codec (lightfield/json_codec.h): the camera reads as any aos camera does, and unknown
//   keys are refused at every level ("stack.json: /camera/fxx: unknown key"). A terrain-following
//   stack stores its surface in the folder (surface.ply: a mesh or a depth map's focal points, in
//   world coordinates; surface.tif: a DEM, with its CRS), its placement under "surface"
//   ({"file", "kind", "origin", "up"}) and one "offset" per slice instead of a "plane".
//
// Throws std::invalid_argument naming the option, file or field; aos::Cancelled on request.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "aos/render/focal_surface.h"
#include "aos/render/integral.h"
#include "aos/util/option_fields.h"

namespace aos {

struct FocalStackOptions {
  // Virtual camera, aperture, views, threads and the variance flag of every slice, and the
  // surface of a terrain-following stack (render.focal_surface not a plane; a plane other than
  // the default is refused: the slices' planes replace it).
  IntegralOptions render;
  // Boundary planes (local frame): slice 0 lies on the first, slice N-1 on the last (for
  // N = 1, the one slice lies midway).
  Plane first_plane = Plane::AtHeight(0.0);
  Plane last_plane = Plane::AtHeight(10.0);
  // A ground plane (local frame) for a plane stack around it (see the contract): the slices
  // then lie parallel to it at first_offset .. last_offset. Unset = first_plane/last_plane.
  std::optional<Plane> ground_plane;
  // Terrain-following stacks (render.focal_surface not a plane) and stacks around ground_plane: the
  // offsets along up of slice 0 and of the last slice, metres. The defaults span 2 m below the surface (a DEM that is a little
  // high) to 30 m above it (the top of a tall forest canopy); 100 slices are then 0.32 m apart.
  double first_offset = -2.0;
  double last_offset = 30.0;
  // Number of slices, 1 .. 100000.
  int slices = 100;

  // Throws std::invalid_argument naming the field (render fields as IntegralOptions::Check).
  void Check(int view_count) const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = FocalStackOptions;
    field(OptionField("render", &O::render, "", Range::Any(),
                      "Virtual camera, aperture, views, threads and variance flag of every "
                      "slice (IntegralOptions); a render.focal_surface that is not a plane "
                      "makes a terrain-following stack (another plane than the default is "
                      "refused)."));
    field(OptionField("first_plane", &O::first_plane, "", Range::Any(),
                      "Boundary plane of slice 0 (local frame)."));
    field(OptionField("last_plane", &O::last_plane, "", Range::Any(),
                      "Boundary plane of slice N-1 (local frame)."));
    field(OptionField("ground_plane", &O::ground_plane, "", Range::Any(),
                      "A ground plane (e.g. estimate_ground(...).plane): the slices then lie "
                      "parallel to it at first_offset .. last_offset along its normal turned "
                      "towards the views; None = first_plane/last_plane."));
    field(OptionField("first_offset", &O::first_offset, "m", Range::Finite(),
                      "Terrain-following stacks (render.focal_surface not a plane) and stacks around "
                      "ground_plane: offset of slice 0 along up, metres."));
    field(OptionField("last_offset", &O::last_offset, "m", Range::Finite(),
                      "Terrain-following stacks and stacks around ground_plane: offset of "
                      "slice N-1 along up, metres."));
    field(OptionField("slices", &O::slices, "", Range::Closed(1, 100000),
                      "Number of slices, 1 .. 100000."));
  }
};

// Whether a stack with these render options follows its surface (render.focal_surface is a mesh,
// a DEM or a depth map) rather than lying on planes.
bool FollowsSurface(const IntegralOptions& render);

// Plane of parameter s in [0, 1] between `first` and `last`, interpolated about `center` as
// described above. Throws std::invalid_argument if a normal is zero or not finite.
Plane InterpolatePlane(const Plane& first, const Plane& last, double s, const Vec3d& center);

// The N slice planes.
std::vector<Plane> StackPlanes(const Plane& first, const Plane& last, int slices,
                               const Vec3d& center);

// PlaneDepth (the depth map of a plane) lives in focal_surface.h.

// The N offsets of a terrain-following stack (see the contract above).
std::vector<double> StackOffsets(double first_offset, double last_offset, int slices);

// Where a stack's slices lie: N planes, or one surface placed once and moved by N offsets.
struct SliceFocus {
  std::vector<Plane> planes;                    // plane stacks: one per slice
  std::shared_ptr<const FocalSurface> surface;  // terrain-following stacks (planes empty)
  SurfacePlacement placement;                   // the surface's origin and up (offset 0)
  std::vector<double> offsets;                  // terrain-following: one per slice, metres

  int size() const;
  // Depth (camera z, metres, float32) of every pixel of `camera` at `cam_from_world` on the
  // focus of its fractional slice index `slice[y * width + x]` (< 0: none, depth 0): for planes
  // the interpolated plane (InterpolatePlane about the camera centre), for a surface the
  // surface at the linearly interpolated offset (FocalSurface::DepthForOffsets, exact). 0 where
  // the ray misses or meets it behind the camera.
  Image DepthOfSlices(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                      const std::vector<float>& slice, int threads) const;
  // The focal plane whose normal the grazing-angle test uses when re-integrating on a depth
  // map: slice 0's plane, or the horizontal plane (normal up) for a surface.
  Plane GrazingPlane() const;
};

// The slices of `options` for `light_field`: StackPlanes about the virtual camera centre, or the
// surface placed for the selected views with StackOffsets. Throws as FocalStackOptions::Check.
SliceFocus ResolveSliceFocus(const LightField& light_field, const FocalStackOptions& options);

struct FocalStack {
  PinholeCamera camera;        // the virtual camera
  Rigid3d cam_from_world;      // its pose (local frame)
  // How the slices were rendered (pose resolved into cam_from_world, pose_view -1): what a
  // robust merge re-integrates with. Stored in stack.json except num_threads.
  IntegralOptions render;
  SliceFocus focus;            // where the slices lie (planes, or a surface and offsets)
  std::vector<Image> images;   // float32, the views' channels
  std::vector<Image> counts;   // uint32
  std::vector<Image> variances;  // float32, empty unless rendered with variance

  int size() const { return focus.size(); }
  // Throws std::invalid_argument if the parts disagree in count or size, if an image or a
  // variance holds a non-finite value, or if an image holds one beyond kMaxStackMagnitude.
  void Check(const std::string& where) const;
};

// The largest magnitude a stack's image and variance samples may have: the merge's focus
// measures square differences of samples in float32, which overflows to infinity (and NaN
// depths and confidences) for magnitudes near 1e19. Real data (8/16-bit units, radiometric
// temperatures) stays far below.
inline constexpr double kMaxStackMagnitude = 1e15;

// "pixel (x, y) channel c is <value>, beyond +-1e15 ..." for the first sample of `image` whose
// magnitude exceeds kMaxStackMagnitude, or nullopt.
std::optional<std::string> DescribeOutOfStackRange(const Image& image);

// Renders every slice and keeps them all (memory grows with N; see RenderFocalStackSlices).
FocalStack RenderFocalStack(const LightField& light_field, const FocalStackOptions& options,
                            ProgressSink* progress = nullptr);

// Renders the slices one at a time, in order, handing each to `on_slice` (which may move from
// the result): memory holds one slice whatever N is. Progress counts slices.
// (Where each slice lies: ResolveSliceFocus.)
using SliceSink = std::function<void(int index, IntegralResult& slice)>;
void RenderFocalStackSlices(const LightField& light_field, const FocalStackOptions& options,
                            const SliceSink& on_slice, ProgressSink* progress = nullptr);

void WriteFocalStack(const std::string& folder, const FocalStack& stack);
FocalStack ReadFocalStack(const std::string& folder);

}  // namespace aos
