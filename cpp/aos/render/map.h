#pragma once
// Maps: an orthographic virtual camera looking straight down, rendered tile by tile through the
// one per-sample route (surface_integral.h, kCylinder aperture), and written as a Cloud-Optimised
// GeoTIFF with GDAL.
//
// Contract
// - Frames. World = light_field.origin + local (lightfield.h). The map's grid is in world x/y:
//   a north-up raster, row 0 at the largest y, column 0 at the smallest x; pixel (col, row) covers
//   [x_min + col * p, x_min + (col + 1) * p] x [y_max - (row + 1) * p, y_max - row * p] and its
//   centre (col + 0.5, row + 0.5) is where its focal point lies. GeoTransform() is GDAL's:
//   (x_min, p, 0, y_max, 0, -p).
// - Up. The map looks along -up, where up is the +z or -z axis, whichever points from the focal
//   surface towards the mean centre of the selected views (geo-referenced and simulated light
//   fields have z up; JKU/F0 poses have z down, and there up is -z). The raster is always written
//   in the frame's own x/y axes: for a z-down frame (x, y, z right-handed) the map therefore shows
//   the ground as seen from below (mirrored against a photograph from above), which is what the
//   frame's coordinates say; GIS tools place every pixel at its x/y correctly.
// - Focal surface: focal_surface (focal_surface.h; default the plane z = 0, local frame), moved
//   by surface_offset along up. A horizontal plane z = h is the plane path (every focal point at
//   z = h + offset * up); a tilted plane, a mesh or a DEM: a pixel's focal point is where the
//   vertical line through its centre, coming down from the up side, first meets the surface
//   (FocalSurface::HeightsAt); pixels whose line misses it get count 0. Every pixel's focal point
//   comes from one function, MapFocalPoints. With a surface, up is the surface's
//   (ResolveSurfacePlacement) and the default extent is the footprints on the horizontal plane
//   through the surface's reference point. A map on a surface that covers none of its pixels
//   (its x/y box holds no pixel centre: refused before rendering; or no pixel has a sample) is
//   refused by CheckSurfaceCovers (focal_surface.h), the check aos-render integral makes, naming
//   the surface and the likely cause (its box beside the map's, its CRS beside the light
//   field's); WriteMapGeoTiff then leaves no file.
// - Views: a view contributes to a pixel's focal point X by integral.h's rules (in front, inside
//   its image, not grazing: min_view_angle_deg against the horizontal) and the cylinder aperture:
//   its centre lies within aperture_radius of the vertical line through X (horizontal distance);
//   infinity = every view, 0 = the single nearest view.
// - Extent: options.extent (world XMIN YMIN XMAX YMAX), or by default the union of the selected
//   views' footprints on the focal surface (their image borders cast onto it), widened outwards
//   to whole multiples of the pixel size when pixel_size is given (with a pixel count, width,
//   the footprints' box is kept and the map is exactly `width` pixels wide). The grid starts at (XMIN, YMAX) and holds
//   ceil(extent / pixel size) pixels per axis (the last column and row may reach past XMAX and
//   below YMIN by less than a pixel). The pixel size is options.pixel_size, or the extent's
//   width / options.width.
// - Tiles: the map is rendered in tiles of tile_size x tile_size pixels; every pixel's arithmetic
//   depends only on its column and row (the focal points are relative to the map's centre, one
//   reference for all tiles), so the result does not depend on the tile size, bit for bit.
//   Memory: one tile's points and image at a time, plus GDAL's block cache while writing.
// - Output values: image is float32 with the views' channels (mean of the samples, in the
//   views' units), count is uint32 (samples per pixel); pixels no view sees get count 0 and
//   image 0 in memory, NaN (the nodata value) in the GeoTIFF.
//
// Throws std::invalid_argument naming the option (pixel_size, width, extent, focal_surface, ...)
// or the file for bad input, aos::Cancelled if the progress sink asks to stop.
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/focal_surface.h"
#include "aos/render/integral.h"
#include "aos/render/surface_integral.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

// The aperture (aperture.h: aperture_radius, view_indices, min_view_angle_deg,
// lens_tolerance_px, num_threads) and the map's grid, focus and tiles below.
struct MapOptions : ApertureOptions {
  // Ground size of a pixel, metres (> 0); 0 = the extent's width / width.
  double pixel_size = 0.0;
  // Map width in pixels when pixel_size is 0 (>= 2); ignored otherwise.
  int width = 0;
  // World XMIN, YMIN, XMAX, YMAX (origin + local, metres); empty = the views' footprints.
  std::vector<double> extent;
  // Where the map focuses (focal_surface.h), as IntegralOptions::focal_surface: a plane (a
  // horizontal one is the exact plane path), a mesh or a DEM; default the plane z = 0.
  FocalSurface focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
  // Metres along up by which focal_surface is moved (1.0 = one metre above the terrain).
  double surface_offset = 0.0;
  // Pixels on a side of a render tile, 16 .. 8192.
  int tile_size = 512;
  // The most pixels (width * height) the map may have: more is refused as a likely mistake of
  // units (the map is streamed tile by tile, so memory does not bound it).
  int64_t max_pixels = 1'000'000'000;

  // Throws std::invalid_argument naming the field. `view_count`: views in the light field.
  // Pixels averaged over fewer views than this are left uncovered (nodata, count 0), as
  // IntegralOptions::min_view_count: the rim of the flight, where occluders do not blur away.
  // 0 or 1 keeps every pixel a view sees.
  int min_view_count = 0;
  void Check(int view_count) const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = MapOptions;
    field(OptionField("pixel_size", &O::pixel_size, "m", Range::FiniteAtLeast(0.0),
                      "Ground size of a pixel, metres (> 0); 0 = the extent's width / width."));
    field(OptionField("width", &O::width, "px", Range::Any(),
                      "Map width in pixels when pixel_size is 0 (>= 2)."));
    field(OptionField("extent", &O::extent, "", Range::Any(),
                      "World [XMIN, YMIN, XMAX, YMAX] (origin + local, metres); [] = the "
                      "selected views' footprints on the focal plane."));
    field(OptionField("focal_surface", &O::focal_surface, "", Range::Any(),
                      "Where the map focuses: a plane (a number is the horizontal plane z = "
                      "that height, local frame), a Mesh, a Heightfield (DEM) or a "
                      "FocalSurface; default the plane z = 0."));
    field(OptionField("surface_offset", &O::surface_offset, "m", Range::Finite(),
                      "Offset of focal_surface along up (towards the views), metres."));
    field(OptionField("tile_size", &O::tile_size, "px", Range::Closed(16, 8192),
                      "Pixels on a side of a render tile, 16 .. 8192."));
    field(OptionField("max_pixels", &O::max_pixels, "px", Range::Closed(4.0, 1e14),
                      "The most pixels (width x height) the map may have; more is refused as "
                      "a likely mistake of units. Raise it for a map that large on purpose."));
    field(OptionField("min_view_count", &O::min_view_count, "", Range::AtLeast(0),
                      "Pixels averaged over fewer views than this are left uncovered (nodata); 0 "
                      "or 1 keeps every pixel a view sees."));
    ApertureOptions::Fields(field);  // aperture.h
  }
};

// The resolved orthographic camera: the map's grid in world x/y and its focal surface.
struct MapGrid {
  double x_min = 0.0;       // world x of the left edge
  double y_max = 0.0;       // world y of the top edge (row 0)
  double pixel_size = 0.0;  // metres
  int width = 0;
  int height = 0;
  Vec3d origin{0.0};        // the light field's origin (world of local zero)
  double focal_height = 0.0;  // local z of the focal plane (offset applied), or of the surface's
                              // reference point
  double up_z = 1.0;        // +1: up is +z; -1: up is -z (z-down frames)
  // The focal surface and its placement, when the map focuses on one (else the plane).
  std::shared_ptr<const FocalSurface> surface;
  SurfacePlacement placement;

  // GDAL's geotransform: (x_min, p, 0, y_max, 0, -p).
  std::array<double, 6> GeoTransform() const;
  // World x, y of the centre of pixel (col, row).
  double CenterX(int64_t col) const { return x_min + (static_cast<double>(col) + 0.5) * pixel_size; }
  double CenterY(int64_t row) const { return y_max - (static_cast<double>(row) + 0.5) * pixel_size; }
};

// Resolves the extent, pixel size, size and up direction; refuses more than options.max_pixels
// pixels or fewer than 2 on a side (naming pixel_size or width, and extent).
MapGrid ResolveMapGrid(const LightField& light_field, const MapOptions& options);

// After a map on a focal surface is rendered (here, or tile by tile on a cluster): refuses it
// when no pixel is covered, `uncovered_pixels` being the sum over its tiles
// (CheckSurfaceCovers, naming the surface, its extent and the map's). No-op on a plane.
void CheckMapCovered(const LightField& light_field, const MapGrid& grid, int64_t uncovered_pixels);

// THE focal points of the map pixels [x0, x0 + w) x [y0, y0 + h): each pixel centre's vertical
// line meets the focal surface (today the plane z = focal_height), relative to the map's centre
// (the reference of every tile).
FocalPoints MapFocalPoints(const MapGrid& grid, int x0, int y0, int w, int h);

// The options of RenderIntegralAtPoints for a map (kCylinder aperture, axis and normal up).
PointIntegralOptions MapPointOptions(const MapGrid& grid, const MapOptions& options);

struct MapSummary {
  MapGrid grid;
  int views_selected = 0;
  int views_used = 0;            // selected views that contributed to at least one pixel
  int64_t samples = 0;           // sum of count
  int64_t uncovered_pixels = 0;  // pixels with count 0
  int tiles = 0;
};

// One rendered tile: pixels [x0, x0 + image.width()) x [y0, y0 + image.height()).
struct MapTile {
  int x0 = 0;
  int y0 = 0;
  const IntegralResult* result = nullptr;
};

// Renders the map tile by tile (rows of tiles top to bottom, left to right), handing each tile
// to `consume` before rendering the next. Progress: one stage "render map", a unit per tile row.
MapSummary RenderMapTiles(const LightField& light_field, const MapOptions& options,
                          const std::function<void(const MapTile&)>& consume,
                          ProgressSink* progress = nullptr);

struct MapResult {
  MapSummary summary;
  Image image;  // float32, width x height x channels (0 where count is 0)
  Image count;  // uint32, width x height
  std::string crs;  // the light field's
};

// The whole map in memory.
MapResult RenderMap(const LightField& light_field, const MapOptions& options,
                    ProgressSink* progress = nullptr);

struct MapWriteOptions {
  // Replace an existing output file (refused otherwise).
  bool force = false;
  // GDAL's block cache while writing, MiB (set for the write, restored after), >= 16.
  int gdal_cache_mb = 128;
};

// Writes a Cloud-Optimised GeoTIFF: bands 1..C the image (float32, NaN = nodata where count is
// 0), band C+1 the count (float32, exact), DEFLATE-compressed (level 1, floating-point
// predictor, on every core), 256-pixel
// blocks, averaged overviews down to one block; geotransform GeoTransform(), CRS `crs` (an
// "EPSG:<code>" or any text OGRSpatialReference::SetFromUserInput reads; empty = none). The tiles go into a tiled
// uncompressed temporary GeoTIFF beside `path` (refused up front where the folder lacks
// MapWriteDiskBytes() of free space), the COG is copied from it into a second temporary name and
// renamed to `path`: a failure or cancel leaves no output and no temporary file.
// Throws std::invalid_argument naming `path` (exists without force, folder missing or not
// writable) or the CRS.
MapSummary WriteMapGeoTiff(const LightField& light_field, const MapOptions& options,
                           const std::string& path, const MapWriteOptions& write = {},
                           ProgressSink* progress = nullptr);
// The same for a map already in memory.
void WriteMapGeoTiff(const MapResult& map, const std::string& path,
                     const MapWriteOptions& write = {});

// Windows of a map, for renders split across processes or machines (python/aos/distributed.py,
// docs/distributed.md): every process resolves the same grid from the same poses
// (ResolveMapGrid reads poses and cameras only), renders windows from the few frames that meet
// them, and one writer assembles the file.

// The selected views (light-field indices, ascending) that may contribute to map pixels
// [x0, x0 + w) x [y0, y0 + h): a view is left out only when the box of the window's focal points
// lies wholly in front of it and projects (through the pinhole, or for a lens model into the
// box of its image border cast back through the lens, widened by 2 %) outside its image widened
// by one pixel, so that it admits none of them (integral.h's inside-the-image rule). Reads poses
// and cameras only; the views need no images. Throws std::invalid_argument naming "window" for a
// window outside the grid.
std::vector<int> MapWindowViews(const LightField& light_field, const MapGrid& grid,
                                const MapOptions& options, int x0, int y0, int w, int h);

// How a map's tiles are spread over Dask (python/aos/distributed, docs/distributed.md): the
// options of `aos-render map --workers/--scheduler` and of aos.distributed.render_map, defined
// here once (the renderer itself is Python).
struct DistributedOptions {
  // Worker processes of a local cluster, >= 0; 0 = none: the CLI renders in its own process;
  // aos.distributed.render_map (always on Dask) starts one worker where it has no client or
  // scheduler.
  int workers = 0;
  // Address of an existing Dask scheduler (e.g. "tcp://10.0.0.5:8786"), whose workers read the
  // frames under the same paths; empty = none. Not with workers.
  std::string scheduler;
  // Decoded frames each worker keeps between tasks, MiB, >= 0 (a task's own frames are always
  // held, so a worker's frames peak at max(cache_mb, one tile's frames)).
  double cache_mb = 1024.0;
  // Decoded frames each worker hands, through shared memory (/dev/shm), to the other workers of
  // its machine whose tiles need them too, MiB, >= 0; 0 = none.
  double share_mb = 512.0;
  // The local cluster also serves Dask's dashboard (a cluster of `scheduler` serves its own);
  // needs workers >= 1.
  bool dashboard = false;
  // Throws std::invalid_argument naming the field.
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = DistributedOptions;
    field(OptionField("workers", &O::workers, "", Range::AtLeast(0),
                      "Worker processes of a local Dask cluster that renders the map's tiles, "
                      ">= 0; 0 = none (the CLI renders in its own process; "
                      "aos.distributed.render_map then starts one worker)."));
    field(OptionField("scheduler", &O::scheduler, "", Range::Any(),
                      "Address of an existing Dask scheduler (tcp://HOST:PORT); '' = none. "
                      "Not with workers."));
    field(OptionField("cache_mb", &O::cache_mb, "MiB", Range::FiniteAtLeast(0.0),
                      "Decoded frames (and, for anomaly imaging, their scores) each Dask "
                      "worker keeps between tasks, MiB, >= 0 (with workers or a scheduler)."));
    field(OptionField("share_mb", &O::share_mb, "MiB", Range::FiniteAtLeast(0.0),
                      "Decoded frames each worker hands to the other workers of its machine "
                      "through shared memory, MiB, >= 0; 0 = none."));
    field(OptionField("dashboard", &O::dashboard, "", Range::Any(),
                      "The local cluster also serves Dask's dashboard; needs workers >= 1."));
  }
};

// A map window: pixels [x0, x0 + w) x [y0, y0 + h).
struct MapWindow {
  int x0 = 0, y0 = 0, w = 0, h = 0;
};

// MapWindowViews of each of `windows`, in their order (the client of a distributed map asks for
// every tile at once).
std::vector<std::vector<int>> MapWindowsViews(const LightField& light_field, const MapGrid& grid,
                                              const MapOptions& options,
                                              const std::vector<MapWindow>& windows);

// Map pixels [x0, x0 + w) x [y0, y0 + h) of `grid` (ResolveMapGrid of this light field's poses
// and `options`), integrated over views `views` only (light-field indices within the options'
// selection; they must hold their images, the others need not). When `views` holds
// MapWindowViews(...) of the window, every pixel is bit for bit RenderMap's: the views left out
// admit no sample there, and each pixel sums its samples in view order whatever the window.
// Throws std::invalid_argument naming "window" or "views".
SurfaceIntegralResult RenderMapWindow(const LightField& light_field, const MapGrid& grid,
                                      const MapOptions& options, int x0, int y0, int w, int h,
                                      const std::vector<int>& views,
                                      ProgressSink* progress = nullptr);

// Writes a map window by window into the GeoTIFF of WriteMapGeoTiff (same bands, blocks,
// overviews and temporary names): windows may come in any order; Commit() makes the COG and
// renames it to `path`. Destroying the writer without a successful Commit() leaves no output
// and no temporary file. Throws std::invalid_argument naming `path`.
class MapGeoTiffWriter {
 public:
  MapGeoTiffWriter(const MapGrid& grid, int channels, const std::string& crs,
                   const std::string& path, const MapWriteOptions& write = {});
  ~MapGeoTiffWriter();
  MapGeoTiffWriter(const MapGeoTiffWriter&) = delete;
  MapGeoTiffWriter& operator=(const MapGeoTiffWriter&) = delete;
  // Pixels [x0, x0 + image.width()) x [y0, y0 + image.height()): image float32 with `channels`
  // channels, count uint32 of the same size.
  void Write(int x0, int y0, const Image& image, const Image& count);
  void Commit(ProgressSink* progress = nullptr);

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

// Checks an output path before any work: it ends in .tif or .tiff (maps are COG GeoTIFFs), its
// folder exists and is writable, it is not a folder, and it does not exist unless write.force. Throws std::invalid_argument naming the path.
void CheckMapOutputPath(const std::string& path, const MapWriteOptions& write);
// The first of those checks alone: the name ends in .tif or .tiff.
void CheckMapOutputExtension(const std::string& path);

// The disk space writing a map of `grid` with `channels` image bands takes beside its output at
// its peak, bytes: the uncompressed temporary GeoTIFF (bands and count as float32, with its
// overview levels) plus an estimate of the COG (half that). MapGeoTiffWriter refuses to start
// where the output's folder has less free space.
uint64_t MapWriteDiskBytes(const MapGrid& grid, int channels);

// Checks that `crs` is empty or a CRS GDAL reads; throws std::invalid_argument naming `where`.
void CheckMapCrs(const std::string& crs, const std::string& where);

}  // namespace aos
