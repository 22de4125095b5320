// Writing maps as Cloud-Optimised GeoTIFFs with GDAL (map.h). GDAL's headers stay in here.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <system_error>
#include <vector>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "aos/geometry/heightfield.h"
#include "aos/render/map.h"
#include "aos/util/error.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

constexpr int kBlockSize = 256;  // COG blocks; overviews go down to one block

// GDAL's messages go to us, not to stderr, while a writer lives; the last one names the cause.
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  static std::string Last() {
    const char* message = CPLGetLastErrorMsg();
    return message != nullptr && *message != '\0' ? std::string(message) : "unknown GDAL error";
  }
};

std::string WktOf(const std::string& crs, const std::string& where) {
  if (crs.empty()) return "";
  OGRSpatialReference srs;
  QuietGdal quiet;
  if (srs.SetFromUserInput(crs.c_str()) != OGRERR_NONE) {
    ThrowInvalid(where + ": crs: '" + crs + "' is not a coordinate reference system GDAL knows (" +
                 QuietGdal::Last() + ")");
  }
  char* wkt = nullptr;
  srs.exportToWkt(&wkt);
  std::string text = wkt != nullptr ? wkt : "";
  CPLFree(wkt);
  return text;
}

struct GdalProgressTarget {
  ProgressSink* sink = nullptr;
  int64_t done = 0;
};

int CPL_STDCALL GdalProgress(double complete, const char*, void* data) {
  auto* target = static_cast<GdalProgressTarget*>(data);
  const int64_t now = static_cast<int64_t>(std::lround(std::clamp(complete, 0.0, 1.0) * 100.0));
  if (now > target->done) {
    ProgressAdvance(target->sink, now - target->done);
    target->done = now;
  }
  return ProgressCancelled(target->sink) ? FALSE : TRUE;
}

// Fails early, before any tile is rendered, where the output's folder cannot hold the
// temporary GeoTIFF and the COG (a full disk would otherwise be found at the end of the run).
void CheckDiskSpace(const MapGrid& grid, int channels, const std::string& path) {
  const fs::path target(path);
  const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code code;
  const fs::space_info space = fs::space(folder, code);
  if (code) return;  // unknown (the writes themselves still fail cleanly)
  const double needed = static_cast<double>(MapWriteDiskBytes(grid, channels));
  if (static_cast<double>(space.available) < needed) {
    const auto size = [](double bytes) {
      return bytes >= 1073741824.0
                 ? FormatNumber(std::round(bytes / 1073741824.0 * 100) / 100) + " GiB"
                 : FormatNumber(std::round(bytes / 1048576.0 * 10) / 10) + " MiB";
    };
    ThrowInvalid(path + ": its folder " + folder.string() + " has " +
                 size(static_cast<double>(space.available)) + " free; writing this " +
                 std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                 " map needs about " + size(needed) +
                 " (the uncompressed temporary GeoTIFF and the COG beside it)");
  }
}

// The temporary tiled GeoTIFF, then the COG copy, then the rename; the destructor removes
// whatever is left unless Commit() succeeded.
class GeoTiffWriter {
 public:
  GeoTiffWriter(const MapGrid& grid, int channels, const std::string& crs, const std::string& path,
                const MapWriteOptions& write)
      : grid_(grid), channels_(channels), path_(path), write_(write) {
    CheckMapOutputPath(path, write);
    const std::string wkt = WktOf(crs, path);
    CheckDiskSpace(grid, channels, path);
    RegisterGdal();
    old_cache_ = GDALGetCacheMax64();
    GDALSetCacheMax64(static_cast<GIntBig>(write.gdal_cache_mb) * 1024 * 1024);
    const fs::path target(path);
    const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
    const std::string stem = "." + target.filename().string() + "." + std::to_string(::getpid());
    tiles_path_ = (folder / (stem + ".tiles.tif")).string();
    part_path_ = (folder / (stem + ".part.tif")).string();
    GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
    if (gtiff == nullptr) ThrowInvalid(path + ": GDAL has no GTiff driver");
    char** options = nullptr;
    options = CSLSetNameValue(options, "TILED", "YES");
    options = CSLSetNameValue(options, "BLOCKXSIZE", std::to_string(kBlockSize).c_str());
    options = CSLSetNameValue(options, "BLOCKYSIZE", std::to_string(kBlockSize).c_str());
    // Uncompressed: the blocks are written once as the tiles come in and read once by the COG
    // copy, which compresses them; compressing them here too (ZSTD level 1) cost the writing
    // process 1.0-1.5 s of CPU and the copy 0.7 s more on a 22.5 MP map (docs/distributed.md), time
    // taken from the workers' cores. The price is disk: MapWriteDiskBytes(), checked above.
    options = CSLSetNameValue(options, "COMPRESS", "NONE");
    options = CSLSetNameValue(options, "BIGTIFF", "IF_SAFER");
    options = CSLSetNameValue(options, "SPARSE_OK", "TRUE");
    QuietGdal quiet;
    dataset_ = gtiff->Create(tiles_path_.c_str(), grid.width, grid.height, channels + 1,
                             GDT_Float32, options);
    CSLDestroy(options);
    if (dataset_ == nullptr) {
      ThrowInvalid(path + ": cannot write a temporary GeoTIFF beside it (" + QuietGdal::Last() + ")");
    }
    std::array<double, 6> transform = grid.GeoTransform();
    dataset_->SetGeoTransform(transform.data());
    if (!wkt.empty()) dataset_->SetProjection(wkt.c_str());
    const char* rgb[] = {"red", "green", "blue", "alpha"};
    for (int band = 1; band <= channels + 1; ++band) {
      GDALRasterBand* raster = dataset_->GetRasterBand(band);
      raster->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
      if (band == channels + 1) {
        raster->SetDescription("count");
      } else if (channels == 1) {
        raster->SetDescription("value");
      } else {
        raster->SetDescription(channels <= 4 ? rgb[band - 1] : ("channel " + std::to_string(band)).c_str());
      }
    }
    if (grid.surface) {
      dataset_->SetMetadataItem("AOS_FOCAL_SURFACE", grid.surface->Describe().c_str());
      dataset_->SetMetadataItem("AOS_SURFACE_OFFSET", FormatNumber(grid.placement.offset).c_str());
    } else {
      dataset_->SetMetadataItem("AOS_FOCAL_HEIGHT", FormatNumber(grid.focal_height).c_str());
    }
    dataset_->SetMetadataItem("AOS_UP", grid.up_z > 0 ? "+z" : "-z");
    // The overview levels the COG gets: as GDAL's COG driver counts them (halving, rounded
    // down, until a level fits in one block), each ceil(size / factor) pixels as GTiff's own
    // overviews (gdaladdo) are, its last row and column over the base pixels left. They are
    // allocated here (empty, sparse) and filled window by window in Write(), so that the end of
    // the map (Commit) only compresses: the averages are made while the tiles come in, on the
    // worker cores' time, not after the last one.
    for (int f = 2, w = grid.width, h = grid.height; w > kBlockSize || h > kBlockSize; f *= 2) {
      factors_.push_back(f);
      w /= 2;
      h /= 2;
    }
    if (!factors_.empty() &&
        dataset_->BuildOverviews("NONE", static_cast<int>(factors_.size()), factors_.data(), 0,
                                 nullptr, nullptr, nullptr) != CE_None) {
      const std::string error = QuietGdal::Last();
      GDALClose(dataset_);  // the destructor does not run for a constructor that throws
      dataset_ = nullptr;
      std::error_code ignored;
      fs::remove(tiles_path_, ignored);
      GDALSetCacheMax64(old_cache_);
      ThrowInvalid(path + ": cannot add overviews to the temporary GeoTIFF (" + error + ")");
    }
  }

  // Radiometric light fields: how the value band reads as temperature (metadata
  // AOS_TEMPERATURE and the band's description), as integral's description says it.
  void SetTemperatures(const Radiometry& radiometry) {
    dataset_->SetMetadataItem("AOS_TEMPERATURE", radiometry.Describe().c_str());
    if (channels_ == 1) {
      dataset_->GetRasterBand(1)->SetDescription(("value (" + radiometry.Describe() + ")").c_str());
    }
  }

  ~GeoTiffWriter() {
    if (dataset_ != nullptr) GDALClose(dataset_);
    std::error_code ignored;
    fs::remove(tiles_path_, ignored);
    if (!committed_) fs::remove(part_path_, ignored);
    GDALSetCacheMax64(old_cache_);
  }

  // Pixels [x0, x0 + w) x [y0, y0 + h): `image` float32 (channels), `count` uint32.
  void Write(int x0, int y0, const Image& image, const Image& count) {
    const int w = image.width(), h = image.height();
    if (image.type() != PixelType::kF32 || image.channels() != channels_ ||
        count.type() != PixelType::kU32 || count.channels() != 1 || count.width() != w ||
        count.height() != h || x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > grid_.width ||
        y0 + h > grid_.height) {
      ThrowInvalid(path_ + ": window " + std::to_string(x0) + "," + std::to_string(y0) + " " +
                   std::to_string(w) + "x" + std::to_string(h) + ": expected a float32 image of " +
                   std::to_string(channels_) + " channels and a uint32 count of its size, inside the " +
                   std::to_string(grid_.width) + "x" + std::to_string(grid_.height) + " map");
    }
    if (dataset_ == nullptr) ThrowInvalid(path_ + ": the map was already committed");
    const int bands = channels_ + 1;
    buffer_.resize(static_cast<size_t>(w) * h * bands);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int row = 0; row < h; ++row) {
      const float* pixel = image.At<float>(0, row);
      const uint32_t* samples = count.At<uint32_t>(0, row);
      float* out = buffer_.data() + static_cast<size_t>(row) * w * bands;
      for (int col = 0; col < w; ++col) {
        for (int c = 0; c < channels_; ++c) {
          out[c] = samples[col] == 0 ? nan : pixel[c];
        }
        out[channels_] = static_cast<float>(samples[col]);
        pixel += channels_;
        out += bands;
      }
    }
    QuietGdal quiet;
    const GSpacing value = sizeof(float);
    if (dataset_->RasterIO(GF_Write, x0, y0, w, h, buffer_.data(), w, h, GDT_Float32, bands,
                           nullptr, value * bands, value * bands * w, value,
                           nullptr) != CE_None) {
      ThrowInvalid(path_ + ": writing the temporary GeoTIFF failed (" + QuietGdal::Last() + ")");
    }
    if (overviews_filled_ && !factors_.empty()) {
      // A window covers whole pixels of every overview level when it starts on a multiple of
      // the largest factor and ends on one or at the map's edge (tiles of 512 pixels do, up to
      // factor 512); otherwise GDAL makes the overviews at the end, from the whole map.
      const int f = factors_.back();
      const bool aligned = x0 % f == 0 && y0 % f == 0 &&
                           ((x0 + w) % f == 0 || x0 + w == grid_.width) &&
                           ((y0 + h) % f == 0 || y0 + h == grid_.height);
      if (aligned) {
        WriteOverviews(x0, y0, w, h);
      } else {
        overviews_filled_ = false;
      }
    }
  }

  // The COG copy and the rename.
  void Commit(ProgressSink* progress) {
    if (dataset_ == nullptr) ThrowInvalid(path_ + ": the map was already committed");
    buffer_.clear();
    buffer_.shrink_to_fit();
    QuietGdal quiet;
    dataset_->FlushCache();
    if (CPLGetLastErrorType() >= CE_Failure) {
      ThrowInvalid(path_ + ": writing the temporary GeoTIFF failed (" + QuietGdal::Last() + ")");
    }
    GDALDriver* cog = GetGDALDriverManager()->GetDriverByName("COG");
    if (cog == nullptr) ThrowInvalid(path_ + ": GDAL has no COG driver (GDAL >= 3.1 needed)");
    char** options = nullptr;
    options = CSLSetNameValue(options, "COMPRESS", "DEFLATE");
    // Level 1: on survey maps (float32 averages, whose low mantissa bits are noise) level 6, the
    // default, spends 1.6x the CPU for files 1 % smaller (docs/distributed.md).
    options = CSLSetNameValue(options, "LEVEL", "1");
    options = CSLSetNameValue(options, "PREDICTOR", "YES");
    options = CSLSetNameValue(options, "BLOCKSIZE", std::to_string(kBlockSize).c_str());
    options = CSLSetNameValue(options, "OVERVIEWS",
                              overviews_filled_ ? "FORCE_USE_EXISTING" : "IGNORE_EXISTING");
    options = CSLSetNameValue(options, "RESAMPLING", "AVERAGE");
    options = CSLSetNameValue(options, "BIGTIFF", "IF_SAFER");
    // Compress the blocks on every core: the copy is the serial end of every map (and of a
    // distributed one, whose workers are idle by then); the pixels do not depend on it.
    options = CSLSetNameValue(options, "NUM_THREADS", "ALL_CPUS");
    GdalProgressTarget target{progress, 0};
    ProgressStart(progress, "write GeoTIFF", 100);
    GDALDataset* copy =
        cog->CreateCopy(part_path_.c_str(), dataset_, FALSE, options, GdalProgress, &target);
    CSLDestroy(options);
    const std::string error = QuietGdal::Last();
    bool closed_ok = true;
    if (copy != nullptr) {
      CPLErrorReset();
      GDALClose(copy);  // void before GDAL 3.7: its failure shows as the last error
      closed_ok = CPLGetLastErrorType() < CE_Failure;
    }
    if (ProgressCancelled(progress)) throw Cancelled();
    if (copy == nullptr || !closed_ok) {
      ThrowInvalid(path_ + ": writing the Cloud-Optimised GeoTIFF failed (" + error + ")");
    }
    ProgressAdvance(progress, 100 - target.done);
    GDALClose(dataset_);
    dataset_ = nullptr;
    std::error_code removed;
    fs::remove(tiles_path_, removed);  // now, not at destruction: the writer may live on
    if (!write_.force && fs::exists(fs::symlink_status(path_))) {
      ThrowInvalid(path_ + ": exists (it appeared while the map was written); force replaces it");
    }
    std::error_code code;
    fs::rename(part_path_, path_, code);
    if (code) ThrowInvalid(path_ + ": cannot move the finished map into place (" + code.message() + ")");
    committed_ = true;
  }

 private:
  MapGrid grid_;
  int channels_;
  std::string path_;
  MapWriteOptions write_;
  std::string tiles_path_, part_path_;
  GDALDataset* dataset_ = nullptr;
  GIntBig old_cache_ = 0;
  bool committed_ = false;
  std::vector<float> buffer_;
  std::vector<int> factors_;      // overview levels: 2, 4, 8, ...
  bool overviews_filled_ = true;  // every window so far filled its overview pixels
  // Per overview pixel of the current window: sums of the valid samples' values (channels),
  // the number of valid base pixels, the sum of the counts and the number of base pixels.
  std::vector<double> sums_, next_sums_;
  std::vector<float> level_;

  // The overview pixels of window [x0, x0 + w) x [y0, y0 + h) (buffer_ holds its bands,
  // pixel-interleaved: channels then count), at every level: the mean of the values over the
  // base pixels with a count > 0 (NaN where none), and the mean count over all base pixels,
  // as GDAL's AVERAGE resampling with the NaN nodata; each level from the exact sums of the
  // base pixels it covers (not a mean of means), a partial block at the map's edge over the
  // pixels it has.
  void WriteOverviews(int x0, int y0, int w, int h) {
    const int bands = channels_ + 1;
    const int stride = channels_ + 3;  // sums..., valid, count sum, pixels
    const float nan = std::numeric_limits<float>::quiet_NaN();
    // Level 1 straight from the base pixels (buffer_), later levels from the sums of the one
    // before: (C + 3) doubles per pixel of level 1, a quarter of the window.
    int lw = (w + 1) / 2, lh = (h + 1) / 2;
    sums_.assign(static_cast<size_t>(lw) * lh * stride, 0.0);
    for (int y = 0; y < h; ++y) {
      const float* in = buffer_.data() + static_cast<size_t>(y) * w * bands;
      for (int x = 0; x < w; ++x, in += bands) {
        double* out = sums_.data() + (static_cast<size_t>(y / 2) * lw + x / 2) * stride;
        if (in[channels_] > 0.0f) {
          for (int c = 0; c < channels_; ++c) out[c] += in[c];
          out[channels_] += 1.0;
        }
        out[channels_ + 1] += in[channels_];
        out[channels_ + 2] += 1.0;
      }
    }
    for (size_t level = 0; level < factors_.size(); ++level) {
      if (level > 0) {
        const int nw = (lw + 1) / 2, nh = (lh + 1) / 2;
        next_sums_.assign(static_cast<size_t>(nw) * nh * stride, 0.0);
        for (int y = 0; y < lh; ++y) {
          for (int x = 0; x < lw; ++x) {
            const double* in = sums_.data() + (static_cast<size_t>(y) * lw + x) * stride;
            double* out = next_sums_.data() + (static_cast<size_t>(y / 2) * nw + x / 2) * stride;
            for (int k = 0; k < stride; ++k) out[k] += in[k];
          }
        }
        std::swap(sums_, next_sums_);
        lw = nw;
        lh = nh;
      }
      level_.resize(static_cast<size_t>(lw) * lh);
      const int f = factors_[level];
      for (int band = 0; band < bands; ++band) {
        for (size_t i = 0; i < level_.size(); ++i) {
          const double* in = sums_.data() + i * stride;
          level_[i] = band < channels_
                          ? (in[channels_] > 0.0 ? static_cast<float>(in[band] / in[channels_]) : nan)
                          : static_cast<float>(in[channels_ + 1] / in[channels_ + 2]);
        }
        GDALRasterBand* overview =
            dataset_->GetRasterBand(band + 1)->GetOverview(static_cast<int>(level));
        if (overview == nullptr ||
            overview->RasterIO(GF_Write, x0 / f, y0 / f, lw, lh, level_.data(), lw, lh,
                               GDT_Float32, 0, 0, nullptr) != CE_None) {
          ThrowInvalid(path_ + ": writing the temporary GeoTIFF's overview " + std::to_string(f) +
                       " failed (" + QuietGdal::Last() + ")");
        }
      }
    }
  }
};

}  // namespace

class MapGeoTiffWriter::Impl : public GeoTiffWriter {
 public:
  using GeoTiffWriter::GeoTiffWriter;
};

MapGeoTiffWriter::MapGeoTiffWriter(const MapGrid& grid, int channels, const std::string& crs,
                                   const std::string& path, const MapWriteOptions& write) {
  if (channels < 1) ThrowInvalid(path + ": channels: must be >= 1 (got " + std::to_string(channels) + ")");
  impl_ = std::make_unique<Impl>(grid, channels, crs, path, write);
}

MapGeoTiffWriter::~MapGeoTiffWriter() = default;

void MapGeoTiffWriter::Write(int x0, int y0, const Image& image, const Image& count) {
  impl_->Write(x0, y0, image, count);
}

void MapGeoTiffWriter::Commit(ProgressSink* progress) { impl_->Commit(progress); }

void CheckMapCrs(const std::string& crs, const std::string& where) { WktOf(crs, where); }

uint64_t MapWriteDiskBytes(const MapGrid& grid, int channels) {
  const uint64_t pixel = static_cast<uint64_t>(channels + 1) * sizeof(float);
  // An uncompressed tiled TIFF stores every block whole, edge blocks included.
  const auto padded = [&](int64_t w, int64_t h) {
    const uint64_t columns = static_cast<uint64_t>((w + kBlockSize - 1) / kBlockSize);
    const uint64_t rows = static_cast<uint64_t>((h + kBlockSize - 1) / kBlockSize);
    return columns * rows * kBlockSize * kBlockSize * pixel;
  };
  uint64_t temporary = padded(grid.width, grid.height);
  // Overview levels as GeoTiffWriter allocates them: halving until one block, each
  // ceil(size / factor) pixels.
  for (int64_t f = 2, w = grid.width, h = grid.height; w > kBlockSize || h > kBlockSize; f *= 2) {
    temporary += padded((grid.width + f - 1) / f, (grid.height + f - 1) / f);
    w /= 2;
    h /= 2;
  }
  temporary += 1 << 20;  // the TIFF's directories and block offsets
  // The COG: float32 with the floating-point predictor and DEFLATE keeps about 40-45 % of the
  // raw bands on survey maps; half the temporary file is a guess, not a bound.
  return temporary + temporary / 2;
}

void CheckMapOutputExtension(const std::string& path) {
  std::string extension = fs::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".tif" && extension != ".tiff") {
    // GDAL would write a GeoTIFF under any name: a "map.png" that no PNG reader opens.
    ThrowInvalid(path + ": a map is written as a Cloud-Optimised GeoTIFF (georeferenced, with a "
                 "count band); give it a .tif or .tiff name");
  }
}

void CheckMapOutputPath(const std::string& path, const MapWriteOptions& write) {
  if (path.empty()) ThrowInvalid("output: the map needs a file name");
  if (write.gdal_cache_mb < 16) ThrowInvalid("gdal_cache_mb: must be >= 16");
  const fs::path target(path);
  const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code code;
  if (!fs::is_directory(folder, code)) {
    ThrowInvalid(path + ": its folder " + folder.string() + " does not exist");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    ThrowInvalid(path + ": its folder " + folder.string() + " is not writable");
  }
  const fs::file_status status = fs::symlink_status(target, code);
  if (fs::exists(status)) {
    if (fs::is_directory(status)) ThrowInvalid(path + ": is a folder");
    if (!write.force) ThrowInvalid(path + ": exists; force replaces it");
  }
  // Last, so that a folder or an existing file is named as such first.
  CheckMapOutputExtension(path);
}

MapSummary WriteMapGeoTiff(const LightField& light_field, const MapOptions& options,
                           const std::string& path, const MapWriteOptions& write,
                           ProgressSink* progress) {
  const MapGrid grid = ResolveMapGrid(light_field, options);
  CheckMapCrs(light_field.crs, path);
  // The render's channels: a masked light field's frames carry a weight channel that the render
  // divides out (lightfield.h).
  const int channels =
      light_field.views.front().image.channels() - (light_field.masked ? 1 : 0);
  GeoTiffWriter writer(grid, channels, light_field.crs, path, write);
  if (light_field.radiometry) writer.SetTemperatures(*light_field.radiometry);
  MapSummary summary = RenderMapTiles(
      light_field, options,
      [&](const MapTile& tile) {
        writer.Write(tile.x0, tile.y0, tile.result->image, tile.result->count);
      },
      progress);
  writer.Commit(progress);
  return summary;
}

void WriteMapGeoTiff(const MapResult& map, const std::string& path, const MapWriteOptions& write) {
  const MapGrid& grid = map.summary.grid;
  if (map.image.empty() || map.image.width() != grid.width || map.image.height() != grid.height ||
      map.count.width() != grid.width || map.count.height() != grid.height) {
    ThrowInvalid(path + ": the map's image and count do not match its grid");
  }
  GeoTiffWriter writer(grid, map.image.channels(), map.crs, path, write);
  // Windows of 1024 x 1024 pixels (aligned with overview factors up to 1024; the writer's
  // buffers stay a few tens of MiB whatever the map's width).
  const int side = kBlockSize * 4;
  const int channels = map.image.channels();
  for (int y0 = 0; y0 < grid.height; y0 += side) {
    const int h = std::min(side, grid.height - y0);
    for (int x0 = 0; x0 < grid.width; x0 += side) {
      const int w = std::min(side, grid.width - x0);
      Image image(w, h, channels, PixelType::kF32);
      Image count(w, h, 1, PixelType::kU32);
      for (int row = 0; row < h; ++row) {
        std::copy_n(map.image.At<float>(x0, y0 + row), static_cast<size_t>(w) * channels,
                    image.At<float>(0, row));
        std::copy_n(map.count.At<uint32_t>(x0, y0 + row), static_cast<size_t>(w),
                    count.At<uint32_t>(0, row));
      }
      writer.Write(x0, y0, image, count);
    }
  }
  writer.Commit(nullptr);
}

}  // namespace aos
