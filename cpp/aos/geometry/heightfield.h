#pragma once
// Height fields (DEM rasters): a regular grid of heights read and written through GDAL (GeoTIFF
// or any raster GDAL reads), the other kind of terrain a focal surface is made of
// (render/focal_surface.h).
//
// Contract
// - Pixel (i, j) (column i, row j, 0-based) holds the height of the point whose WORLD x, y is
//   the geotransform applied to its centre: x = gt[0] + (i + 0.5) gt[1], y = gt[3] + (j + 0.5)
//   gt[5] (GDAL's convention: gt[0], gt[3] are the outer corner of pixel (0, 0)). Heights are
//   metres in the same world frame (for a light field: world = LightField::origin + local).
//   Rotated or sheared geotransforms (gt[2], gt[4] != 0) are refused.
// - Nodata pixels (the band's nodata value, or NaN) are NaN in `heights`, and so are blocks the
//   file does not hold (a sparse GeoTIFF, areas no VRT source covers) when the band declares a
//   nodata value; without one GDAL would read them as heights of 0, and the file is refused.
//   A raster without a
//   CRS is allowed: crs_wkt is then empty (its coordinates are taken as the light field's world
//   frame as they are). A raster without a geotransform is refused (its pixels have no place).
// - Only band 1 is read.
// - Every valid height and every pixel centre's x, y lies within +-kMaxSurfaceCoordinate (1e9 m,
//   mesh.h: what the float ray cast of focal surfaces can hold); a height beyond it (an
//   undeclared nodata value such as -3.4e38) is refused naming its pixel (column, row).
//
// Throws std::invalid_argument naming the file and the field: unreadable file, no or rotated or
// degenerate geotransform, more than kMaxHeightfieldPixels pixels or more than the memory budget
// holds (util/memory.h), a height or pixel centre beyond kMaxSurfaceCoordinate, every pixel
// nodata, blocks without data and no nodata value.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "aos/geometry/mesh.h"

namespace aos {

// Largest raster read as a height field: 2^28 pixels (1 GiB of float32 heights; its mesh for ray
// casting takes about 20 times that).
inline constexpr int64_t kMaxHeightfieldPixels = int64_t{1} << 28;

struct Heightfield {
  int width = 0;
  int height = 0;
  // GDAL geotransform: x = gt[0] + col gt[1] + row gt[2], y = gt[3] + col gt[4] + row gt[5]
  // for continuous pixel coordinates (col, row); gt[2] = gt[4] = 0 here.
  std::array<double, 6> geotransform{0.0, 1.0, 0.0, 0.0, 0.0, -1.0};
  // The raster's CRS as WKT (read), or WKT or any string GDAL's SetFromUserInput takes, such as
  // "EPSG:32633" (written); empty when it has none.
  std::string crs_wkt;
  std::vector<float> heights;  // row-major, width x height, metres; NaN = nodata
  // The file it was read from (ReadHeightfield), which messages about it name; "" when built in
  // memory.
  std::string source;

  float At(int column, int row) const {
    return heights[static_cast<size_t>(row) * static_cast<size_t>(width) + static_cast<size_t>(column)];
  }
  // World x, y of pixel (column, row)'s centre.
  double CenterX(int column) const { return geotransform[0] + (column + 0.5) * geotransform[1]; }
  double CenterY(int row) const { return geotransform[3] + (row + 0.5) * geotransform[5]; }

  // Throws std::invalid_argument ("<where>: <field>: ...") for a size that does not match the
  // heights, an absurd size, a rotated, non-finite or zero-pixel-size geotransform, a raster
  // reaching beyond kMaxSurfaceCoordinate, an infinite height or one beyond
  // kMaxSurfaceCoordinate, or no valid height at all.
  void Check(const std::string& where) const;
};

// Registers GDAL's drivers, once per process (every GDAL user in aos calls it first). It also
// keeps libtiff's diagnostics about TIFF files GDAL is not handling off stderr: once GDAL's GTiff
// driver has run, libtiff reports through GDAL for every library in the process, and OpenImageIO's
// TIFF writes (image_io.h) then printed harmless "ERROR 1: TIFFSetField: ... Unknown tag 306" /
// "TIFFWriteDirectorySec: Out of memory" lines although the files were complete. Those two
// messages only are dropped; every other GDAL or libtiff message still reaches GDAL's default
// handler.
void RegisterGdal();

// Reads band 1 of a GDAL raster. See the contract above.
Heightfield ReadHeightfield(const std::string& path);

// Refuses (std::invalid_argument naming it) a path without a .tif or .tiff extension: a height
// field is written as a GeoTIFF whatever its name. Callers check before the work.
void CheckHeightfieldOutputName(const std::string& path);

// Writes a single-band float32 GeoTIFF (nodata = NaN, the CRS when crs_wkt is set), under a
// temporary name in the destination folder renamed into place when complete. Refuses an existing
// file unless `overwrite`, and a name CheckHeightfieldOutputName refuses. Throws
// std::invalid_argument naming the file.
void WriteHeightfield(const std::string& path, const Heightfield& heightfield,
                      bool overwrite = false);

// The height field as a triangle mesh in world coordinates: one vertex per valid pixel at its
// centre, two triangles per cell of 2 x 2 pixel centres whose four heights are all valid (split
// along the diagonal from (i, j) to (i + 1, j + 1)). Cells touching a nodata pixel are left out
// (rays through them miss). Throws std::invalid_argument if no cell is complete.
Mesh HeightfieldToMesh(const Heightfield& heightfield, const std::string& where = "");

}  // namespace aos
