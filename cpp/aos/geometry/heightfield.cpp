#include "aos/geometry/heightfield.h"

#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>

#include <gdal.h>
#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <ogr_srs_api.h>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/memory.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

// The two libtiff messages OpenImageIO's TIFF writes raise through GDAL's handler once GDAL's
// GTiff driver has run ("TIFFSetField:<file>: Unknown tag 306" for the DateTime tag, then
// "TIFFWriteDirectorySec:Out of memory"), on files that are complete. Only these are dropped:
// every other message, libtiff's included, still reaches GDAL's default handler.
void CPL_STDCALL FilterLibtiffMessages(CPLErr level, CPLErrorNum number, const char* message) {
  if (message != nullptr &&
      ((std::strncmp(message, "TIFFSetField:", 13) == 0 &&
        std::strstr(message, ": Unknown tag 306") != nullptr) ||
       std::strcmp(message, "TIFFWriteDirectorySec:Out of memory") == 0)) {
    return;
  }
  CPLDefaultErrorHandler(level, number, message);
}

}  // namespace

void RegisterGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(FilterLibtiffMessages);
  });
}

namespace {

std::string GdalMessage() {
  const char* message = CPLGetLastErrorMsg();
  return message != nullptr && *message != '\0' ? std::string(" (GDAL: ") + message + ")"
                                                 : std::string();
}

// Keeps GDAL's own error printing off stderr while in scope (library code never prints); the
// message is still read with CPLGetLastErrorMsg.
struct QuietGdal {
  QuietGdal() { CPLPushErrorHandler(CPLQuietErrorHandler); }
  ~QuietGdal() { CPLPopErrorHandler(); }
};

struct DatasetCloser {
  GDALDatasetH dataset = nullptr;
  ~DatasetCloser() {
    if (dataset != nullptr) GDALClose(dataset);
  }
};

}  // namespace

void Heightfield::Check(const std::string& where) const {
  if (width < 1 || height < 1 ||
      static_cast<int64_t>(width) * static_cast<int64_t>(height) > kMaxHeightfieldPixels) {
    ThrowInvalid(Where(where, "size: " + std::to_string(width) + " x " + std::to_string(height) +
                                  " pixels is not 1 .. " + std::to_string(kMaxHeightfieldPixels) +
                                  " pixels"));
  }
  if (heights.size() != static_cast<size_t>(width) * static_cast<size_t>(height)) {
    ThrowInvalid(Where(where, "heights: " + std::to_string(heights.size()) + " values for " +
                                  std::to_string(width) + " x " + std::to_string(height) +
                                  " pixels"));
  }
  for (double value : geotransform) {
    if (!std::isfinite(value)) ThrowInvalid(Where(where, "geotransform: not finite"));
  }
  if (geotransform[2] != 0.0 || geotransform[4] != 0.0) {
    ThrowInvalid(Where(where, "geotransform: rotated or sheared rasters are not supported "
                              "(row/column terms " + FormatNumber(geotransform[2]) + ", " +
                              FormatNumber(geotransform[4]) + "); warp it north-up first "
                              "(gdalwarp)"));
  }
  if (geotransform[1] == 0.0 || geotransform[5] == 0.0) {
    ThrowInvalid(Where(where, "geotransform: the pixel size is zero"));
  }
  // The raster's outer corners bound every pixel centre (x and y are monotonic in column, row).
  const double corners[2][2] = {{geotransform[0], geotransform[0] + width * geotransform[1]},
                                {geotransform[3], geotransform[3] + height * geotransform[5]}};
  for (int axis = 0; axis < 2; ++axis) {
    for (double value : corners[axis]) {
      const std::string problem = SurfaceCoordinateProblem(value);
      if (!problem.empty()) {
        ThrowInvalid(Where(where, std::string("geotransform: the raster's ") + "xy"[axis] +
                                      " range reaches a value that " + problem));
      }
    }
  }
  bool any_valid = false;
  for (size_t i = 0; i < heights.size(); ++i) {
    if (std::isnan(heights[i])) continue;
    const std::string problem = SurfaceCoordinateProblem(heights[i]);
    if (!problem.empty()) {
      ThrowInvalid(Where(where, "heights: pixel (" + std::to_string(i % width) + ", " +
                                    std::to_string(i / width) + ") (column, row) " + problem));
    }
    any_valid = true;
  }
  if (!any_valid) ThrowInvalid(Where(where, "heights: every pixel is nodata"));
}

Heightfield ReadHeightfield(const std::string& path) {
  CheckRegularFile(path, "height field");
  RegisterGdal();
  QuietGdal quiet;
  CPLErrorReset();
  DatasetCloser closer;
  closer.dataset = GDALOpen(path.c_str(), GA_ReadOnly);
  if (closer.dataset == nullptr) {
    ThrowInvalid(path + ": height field: GDAL cannot read it as a raster" + GdalMessage());
  }
  GDALDatasetH dataset = closer.dataset;
  Heightfield field;
  const int64_t width = GDALGetRasterXSize(dataset), height = GDALGetRasterYSize(dataset);
  if (GDALGetRasterCount(dataset) < 1) ThrowInvalid(path + ": height field: the raster has no band");
  if (width < 1 || height < 1 || width * height > kMaxHeightfieldPixels) {
    ThrowInvalid(path + ": size: " + std::to_string(width) + " x " + std::to_string(height) +
                 " pixels is not 1 .. " + std::to_string(kMaxHeightfieldPixels) + " pixels");
  }
  field.width = static_cast<int>(width);
  field.height = static_cast<int>(height);
  double gt[6];
  if (GDALGetGeoTransform(dataset, gt) != CE_None) {
    ThrowInvalid(path + ": geotransform: the raster has none (its pixels have no place in the "
                        "world)");
  }
  for (int i = 0; i < 6; ++i) field.geotransform[static_cast<size_t>(i)] = gt[i];
  const char* wkt = GDALGetProjectionRef(dataset);
  field.crs_wkt = wkt != nullptr ? wkt : "";
  GDALRasterBandH band = GDALGetRasterBand(dataset, 1);
  CheckMemoryBudget(SaturatingProduct({static_cast<uint64_t>(width), static_cast<uint64_t>(height),
                                       sizeof(float)}),
                    path + ": size: " + std::to_string(width) + " x " + std::to_string(height) +
                        " pixels",
                    "the heights as float32");
  field.heights.resize(static_cast<size_t>(width * height));
  if (GDALRasterIO(band, GF_Read, 0, 0, field.width, field.height, field.heights.data(),
                   field.width, field.height, GDT_Float32, 0, 0) != CE_None) {
    ThrowInvalid(path + ": band 1: cannot read the heights" + GdalMessage());
  }
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  // Blocks the file does not hold (strips or tiles with no data: a sparse GeoTIFF, size tags
  // claiming more than was written; areas no source covers in a VRT) come back from GDAL as the
  // nodata value, holes, when the raster declares one, and as heights of 0 that look real when
  // it declares none: refused then.
  double covered_percent = 100.0;
  const int coverage = GDALGetDataCoverageStatus(band, 0, 0, field.width, field.height, 0,
                                                 &covered_percent);
  if (!has_nodata && (coverage & GDAL_DATA_COVERAGE_STATUS_EMPTY) != 0) {
    const double empty = 100.0 - covered_percent;
    ThrowInvalid(path + ": band 1: " +
                 (empty < 0.1 ? std::string("under 0.1") : FormatNumber(std::round(empty * 10) / 10)) +
                 " % of the raster has no data in the file (missing strips or tiles, or areas no "
                 "source covers) and it declares no nodata value, so GDAL would read heights of "
                 "0 there; declare a nodata value (gdal_translate -a_nodata) or write every block");
  }
  if (has_nodata) {
    const float nodata_f = static_cast<float>(nodata);
    for (float& value : field.heights) {
      if (value == nodata_f) value = std::numeric_limits<float>::quiet_NaN();
    }
  }
  field.Check(path);
  field.source = path;
  return field;
}

void CheckHeightfieldOutputName(const std::string& path) {
  std::string extension = fs::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".tif" && extension != ".tiff") {
    ThrowInvalid(path + ": a height field is written as a GeoTIFF; give it a .tif or .tiff name");
  }
}

void WriteHeightfield(const std::string& path, const Heightfield& heightfield, bool overwrite) {
  CheckHeightfieldOutputName(path);
  heightfield.Check(path);
  std::error_code error;
  if (!overwrite && fs::exists(path, error)) {
    ThrowInvalid(path + ": the file exists (not overwritten)");
  }
  CheckOutputPath(path, {}, "height field");
  RegisterGdal();
  QuietGdal quiet;
  PendingFile pending(path);
  {
    GDALDriverH driver = GDALGetDriverByName("GTiff");
    if (driver == nullptr) ThrowInvalid(path + ": GDAL has no GTiff driver");
    char** create_options = nullptr;
    create_options = CSLSetNameValue(create_options, "COMPRESS", "DEFLATE");
    create_options = CSLSetNameValue(create_options, "PREDICTOR", "3");
    create_options = CSLSetNameValue(create_options, "TILED", "YES");
    CPLErrorReset();
    DatasetCloser closer;
    closer.dataset = GDALCreate(driver, pending.TempPath().c_str(), heightfield.width,
                                heightfield.height, 1, GDT_Float32, create_options);
    CSLDestroy(create_options);
    if (closer.dataset == nullptr) ThrowInvalid(path + ": cannot create the GeoTIFF" + GdalMessage());
    double gt[6];
    for (int i = 0; i < 6; ++i) gt[i] = heightfield.geotransform[static_cast<size_t>(i)];
    GDALSetGeoTransform(closer.dataset, gt);
    if (!heightfield.crs_wkt.empty()) {
      // WKT, or any CRS string GDAL understands ("EPSG:32633"), stored as WKT.
      OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
      char* wkt = nullptr;
      const bool parsed = OSRSetFromUserInput(srs, heightfield.crs_wkt.c_str()) == OGRERR_NONE &&
                          OSRExportToWkt(srs, &wkt) == OGRERR_NONE;
      const bool set = parsed && GDALSetProjection(closer.dataset, wkt) == CE_None;
      CPLFree(wkt);
      OSRDestroySpatialReference(srs);
      if (!set) ThrowInvalid(path + ": crs_wkt: GDAL refuses the CRS '" + heightfield.crs_wkt + "'" + GdalMessage());
    }
    GDALRasterBandH band = GDALGetRasterBand(closer.dataset, 1);
    GDALSetRasterNoDataValue(band, std::numeric_limits<double>::quiet_NaN());
    std::vector<float> heights = heightfield.heights;
    if (GDALRasterIO(band, GF_Write, 0, 0, heightfield.width, heightfield.height, heights.data(),
                     heightfield.width, heightfield.height, GDT_Float32, 0, 0) != CE_None) {
      ThrowInvalid(path + ": cannot write the heights" + GdalMessage());
    }
    GDALClose(closer.dataset);
    closer.dataset = nullptr;
    if (CPLGetLastErrorType() >= CE_Failure) {
      ThrowInvalid(path + ": writing the GeoTIFF failed" + GdalMessage());
    }
  }
  pending.Commit();
}

Mesh HeightfieldToMesh(const Heightfield& heightfield, const std::string& where) {
  heightfield.Check(where);
  const int w = heightfield.width, h = heightfield.height;
  Mesh mesh;
  std::vector<int> index(static_cast<size_t>(w) * static_cast<size_t>(h), -1);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const float z = heightfield.At(i, j);
      if (std::isnan(z)) continue;
      index[static_cast<size_t>(j) * w + i] = static_cast<int>(mesh.vertices.size());
      mesh.vertices.emplace_back(heightfield.CenterX(i), heightfield.CenterY(j), z);
    }
  }
  for (int j = 0; j + 1 < h; ++j) {
    for (int i = 0; i + 1 < w; ++i) {
      const int a = index[static_cast<size_t>(j) * w + i];
      const int b = index[static_cast<size_t>(j) * w + i + 1];
      const int c = index[static_cast<size_t>(j + 1) * w + i];
      const int d = index[static_cast<size_t>(j + 1) * w + i + 1];
      if (a < 0 || b < 0 || c < 0 || d < 0) continue;
      mesh.triangles.push_back({a, b, d});
      mesh.triangles.push_back({a, d, c});
    }
  }
  if (mesh.triangles.empty()) {
    ThrowInvalid(Where(where, "heights: no cell of 2 x 2 valid pixels (a surface needs at least "
                              "one)"));
  }
  return mesh;
}

}  // namespace aos
