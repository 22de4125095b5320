#include "aos/sfm/colmap_model.h"


#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <string_view>
#include <system_error>
#include <unordered_set>
#include <utility>

#include "aos/image/image_io.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/parallel.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

// COLMAP's camera models by binary id (src/colmap/sensor/models.h), with their parameter counts.
struct ModelInfo {
  const char* name;
  int num_params;
};
constexpr ModelInfo kModels[] = {
    {"SIMPLE_PINHOLE", 3},       {"PINHOLE", 4},          {"SIMPLE_RADIAL", 4},
    {"RADIAL", 5},               {"OPENCV", 8},           {"OPENCV_FISHEYE", 8},
    {"FULL_OPENCV", 12},         {"FOV", 5},              {"SIMPLE_RADIAL_FISHEYE", 4},
    {"RADIAL_FISHEYE", 5},       {"THIN_PRISM_FISHEYE", 12},
    {"RAD_TAN_THIN_PRISM_FISHEYE", 16},                   {"SIMPLE_DIVISION", 4},
    {"DIVISION", 5},             {"SIMPLE_FISHEYE", 3},   {"FISHEYE", 4},
    {"EUCM", 6},                 {"EQUIRECTANGULAR", 2}};
constexpr int kNumModels = static_cast<int>(sizeof(kModels) / sizeof(kModels[0]));

constexpr uint64_t kNoPoint3D = std::numeric_limits<uint64_t>::max();
constexpr uint64_t kMaxSide = static_cast<uint64_t>(std::numeric_limits<int>::max());
constexpr const char* kFrameExtensions[] = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr"};

std::string Quoted(std::string_view text) { return "\"" + std::string(text) + "\""; }

// A token or line from a file for messages, cut to 60 characters.
std::string Excerpt(std::string_view text) {
  std::string shown(text.substr(0, 60));
  if (text.size() > 60) shown += "...";
  return "\"" + shown + "\"";
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// Whether something is at `path` (a FIFO, a device or a folder too: the reader then refuses it
// by name, instead of the model folder being called "not a COLMAP model").
bool IsFile(const fs::path& path) {
  std::error_code error;
  return fs::exists(path, error);
}

// Rotation of the unit quaternion (w, x, y, z) (Hamilton convention, as Eigen's, which COLMAP
// uses). `q` must be normalised.
Mat3d RotationFromQuaternion(const std::array<double, 4>& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return MatFromRows(Vec3d(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
                     Vec3d(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
                     Vec3d(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)));
}

// ---------------------------------------------------------------------------------------------
// Entries and their checks, shared by both formats. `fail(field, reason)` throws with the
// file/line/entry prefix of the format being read.

template <typename Fail>
void CheckFinite(double value, const char* field, const Fail& fail) {
  if (!std::isfinite(value)) fail(field, "is not finite");
}

template <typename Fail>
int SideFrom(uint64_t value, const char* field, const Fail& fail) {
  if (value < 1 || value > kMaxSide) {
    fail(field, "must be a whole number in [1, " + std::to_string(kMaxSide) + "] (got " +
                    std::to_string(value) + ")");
  }
  return static_cast<int>(value);
}

template <typename Fail>
Rigid3d PoseFrom(const std::array<double, 4>& qvec, const Vec3d& tvec, const Fail& fail) {
  for (double value : qvec) CheckFinite(value, "QW..QZ", fail);
  for (int k = 0; k < 3; ++k) CheckFinite(tvec[k], "TX..TZ", fail);
  const double norm = std::sqrt(qvec[0] * qvec[0] + qvec[1] * qvec[1] + qvec[2] * qvec[2] +
                                qvec[3] * qvec[3]);
  if (!(norm > 0.0) || !std::isfinite(norm)) fail("QW..QZ", "zero quaternion (no rotation)");
  const std::array<double, 4> unit = {qvec[0] / norm, qvec[1] / norm, qvec[2] / norm,
                                      qvec[3] / norm};
  Rigid3d pose;
  pose.rotation = RotationFromQuaternion(unit);
  pose.translation = tvec;
  return pose;
}

// ---------------------------------------------------------------------------------------------
// Text files.

// Whitespace-separated tokens of a line (COLMAP separates by single spaces; tabs and runs of
// spaces are accepted too).
std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

std::string_view Trim(std::string_view text) {
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) {
    text.remove_prefix(1);
  }
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) {
    text.remove_suffix(1);
  }
  return text;
}

// Reads a text file line by line; `Fail` messages carry "<path>: line <n>: <entry>: ".
class TextReader {
 public:
  TextReader(std::string path, ProgressSink* progress)
      : path_(std::move(path)), progress_(progress) {
    CheckRegularFile(path_, "COLMAP model file");
    file_.open(path_, std::ios::binary);
    if (!file_) ThrowInvalid(path_ + ": cannot open the file");
  }

  // The next line that is neither blank nor a comment; false at the end.
  bool NextEntryLine(std::string_view* line) {
    while (NextLine(line)) {
      const std::string_view trimmed = Trim(*line);
      if (trimmed.empty() || trimmed.front() == '#') continue;
      *line = trimmed;
      return true;
    }
    return false;
  }
  // The next line whatever it holds; false at the end.
  bool NextLine(std::string_view* line) {
    if (!std::getline(file_, buffer_)) {
      if (file_.bad()) ThrowInvalid(path_ + ": read error after line " + std::to_string(line_));
      return false;
    }
    ++line_;
    if ((line_ & 4095) == 0 && ProgressCancelled(progress_)) throw Cancelled();
    *line = buffer_;
    return true;
  }

  void SetEntry(const char* kind, std::string_view id) {
    entry_ = std::string(kind) + " " + std::string(id.substr(0, 40));
  }
  [[noreturn]] void Fail(const std::string& field, const std::string& reason) const {
    std::string message = path_ + ": line " + std::to_string(line_);
    if (!entry_.empty()) message += ": " + entry_;
    if (!field.empty()) message += ": " + field;
    ThrowInvalid(message + ": " + reason);
  }
  auto Failer() const {
    return [this](const std::string& field, const std::string& reason) { Fail(field, reason); };
  }

  double Double(std::string_view token, const std::string& field) const {
    std::string_view digits = token;
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
    double value = 0.0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (error != std::errc() || end != digits.data() + digits.size() || digits.empty()) {
      Fail(field, Excerpt(token) + " is not a number");
    }
    if (!std::isfinite(value)) Fail(field, Excerpt(token) + " is not finite");
    return value;
  }
  uint64_t Unsigned(std::string_view token, const std::string& field, uint64_t max) const {
    uint64_t value = 0;
    const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc() || end != token.data() + token.size() || token.empty() ||
        value > max) {
      Fail(field, Excerpt(token) + " is not a whole number in [0, " + std::to_string(max) + "]");
    }
    return value;
  }

 private:
  std::string path_;
  ProgressSink* progress_ = nullptr;  // polled for cancellation every 4096 entries
  std::ifstream file_;
  std::string buffer_;
  size_t line_ = 0;
  std::string entry_;
};

void ReadCamerasText(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  TextReader reader(path, progress);
  std::string_view line;
  while (reader.NextEntryLine(&line)) {
    const auto tokens = Tokens(line);
    reader.SetEntry("camera", tokens[0]);
    if (tokens.size() < 4) {
      reader.Fail("", "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], got " + Excerpt(line));
    }
    ColmapCamera camera;
    camera.camera_id =
        static_cast<uint32_t>(reader.Unsigned(tokens[0], "CAMERA_ID", 0xffffffffu));
    camera.model = std::string(tokens[1]);
    const int num_params = ColmapModelNumParams(camera.model);
    if (num_params < 0) reader.Fail("MODEL", "unknown COLMAP camera model " + Excerpt(tokens[1]));
    const auto fail = reader.Failer();
    camera.width = SideFrom(reader.Unsigned(tokens[2], "WIDTH", kMaxSide), "WIDTH", fail);
    camera.height = SideFrom(reader.Unsigned(tokens[3], "HEIGHT", kMaxSide), "HEIGHT", fail);
    if (tokens.size() - 4 != static_cast<size_t>(num_params)) {
      reader.Fail("PARAMS", "model " + camera.model + " has " + std::to_string(num_params) +
                                " parameters, the line gives " +
                                std::to_string(tokens.size() - 4));
    }
    for (int i = 0; i < num_params; ++i) {
      camera.params.push_back(
          reader.Double(tokens[4 + i], "PARAMS[" + std::to_string(i) + "]"));
    }
    model->cameras.push_back(std::move(camera));
  }
}

void ReadImagesText(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  TextReader reader(path, progress);
  std::string_view line;
  while (reader.NextEntryLine(&line)) {
    const auto tokens = Tokens(line);
    reader.SetEntry("image", tokens[0]);
    if (tokens.size() < 10) {
      reader.Fail("", "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got " +
                          Excerpt(line));
    }
    ColmapImage image;
    image.image_id = static_cast<uint32_t>(reader.Unsigned(tokens[0], "IMAGE_ID", 0xffffffffu));
    const char* q_fields[] = {"QW", "QX", "QY", "QZ"};
    const char* t_fields[] = {"TX", "TY", "TZ"};
    std::array<double, 4> qvec{};
    Vec3d tvec(0.0);
    for (int k = 0; k < 4; ++k) qvec[k] = reader.Double(tokens[1 + k], q_fields[k]);
    for (int k = 0; k < 3; ++k) tvec[k] = reader.Double(tokens[5 + k], t_fields[k]);
    image.cam_from_world = PoseFrom(qvec, tvec, reader.Failer());
    image.camera_id = static_cast<uint32_t>(reader.Unsigned(tokens[8], "CAMERA_ID", 0xffffffffu));
    // NAME: the rest of the line (a name may contain spaces).
    image.name = std::string(Trim(line.substr(tokens[9].data() - line.data())));
    std::string_view points_line;
    if (reader.NextLine(&points_line)) {
      const auto values = Tokens(points_line);
      if (values.size() % 3 != 0) {
        reader.Fail("POINTS2D", "expected X Y POINT3D_ID triples, got " +
                                    std::to_string(values.size()) + " values");
      }
      image.num_points2d = values.size() / 3;
      for (size_t i = 0; i < image.num_points2d; ++i) {
        const std::string field = "POINTS2D[" + std::to_string(i) + "]";
        reader.Double(values[3 * i], field + ".X");
        reader.Double(values[3 * i + 1], field + ".Y");
        if (values[3 * i + 2] != "-1") {
          reader.Unsigned(values[3 * i + 2], field + ".POINT3D_ID", kNoPoint3D - 1);
          ++image.num_observations;
        }
      }
    }
    model->images.push_back(std::move(image));
  }
}

void ReadPointsText(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  TextReader reader(path, progress);
  std::string_view line;
  while (reader.NextEntryLine(&line)) {
    const auto tokens = Tokens(line);
    reader.SetEntry("point", tokens[0]);
    if (tokens.size() < 8 || (tokens.size() - 8) % 2 != 0) {
      reader.Fail("", "expected POINT3D_ID X Y Z R G B ERROR then IMAGE_ID POINT2D_IDX pairs, "
                      "got " + std::to_string(tokens.size()) + " values");
    }
    ColmapPoint point;
    point.point_id = reader.Unsigned(tokens[0], "POINT3D_ID", kNoPoint3D - 1);
    const char* xyz[] = {"X", "Y", "Z"};
    const char* rgb[] = {"R", "G", "B"};
    for (int k = 0; k < 3; ++k) point.position[k] = reader.Double(tokens[1 + k], xyz[k]);
    for (int k = 0; k < 3; ++k) {
      point.color[k] = static_cast<uint8_t>(reader.Unsigned(tokens[4 + k], rgb[k], 255));
    }
    point.error_px = reader.Double(tokens[7], "ERROR");
    point.track_length = (tokens.size() - 8) / 2;
    for (size_t i = 0; i < point.track_length; ++i) {
      const std::string field = "TRACK[" + std::to_string(i) + "]";
      reader.Unsigned(tokens[8 + 2 * i], field + ".IMAGE_ID", 0xffffffffu);
      reader.Unsigned(tokens[9 + 2 * i], field + ".POINT2D_IDX", 0xffffffffu);
    }
    model->points.push_back(point);
  }
}

// ---------------------------------------------------------------------------------------------
// Binary files.

// Sequential little-endian reads through a buffer, every read checked against the file size.
class BinaryReader {
 public:
  BinaryReader(std::string path, ProgressSink* progress)
      : path_(std::move(path)), progress_(progress) {
    size_ = CheckRegularFile(path_, "COLMAP model file");
    file_.open(path_, std::ios::binary);
    if (!file_) ThrowInvalid(path_ + ": cannot open the file");
  }

  uint64_t Remaining() const { return size_ - offset_; }
  uint64_t Offset() const { return offset_; }

  // The entry being read, for messages: "<kind> <index> of <count>" and its id once known.
  void SetEntry(const char* kind, uint64_t index, uint64_t count) {
    if ((index & 4095) == 4095 && ProgressCancelled(progress_)) throw Cancelled();
    kind_ = kind;
    index_ = index;
    count_ = count;
    has_id_ = false;
  }
  void SetId(uint64_t id) {
    id_ = id;
    has_id_ = true;
  }
  [[noreturn]] void Fail(const std::string& field, const std::string& reason) const {
    std::string message = path_;
    if (kind_ != nullptr) {
      message += ": " + std::string(kind_) + " " + std::to_string(index_) + " of " +
                 std::to_string(count_);
      if (has_id_) message += " (id " + std::to_string(id_) + ")";
    }
    if (!field.empty()) message += ": " + field;
    ThrowInvalid(message + ": " + reason);
  }
  auto Failer() const {
    return [this](const std::string& field, const std::string& reason) { Fail(field, reason); };
  }

  // Refuses a count whose entries (at least `min_bytes` each) cannot fit in the rest of the file.
  void CheckCount(uint64_t count, uint64_t min_bytes, const std::string& field) const {
    if (count > Remaining() / min_bytes) {
      Fail(field, std::to_string(count) + " entries of at least " + std::to_string(min_bytes) +
                      " bytes cannot fit in the " + std::to_string(Remaining()) +
                      " bytes left (damaged or not a COLMAP file)");
    }
  }

  uint64_t U64(const char* field) { return Bytes<8>(field); }
  uint32_t U32(const char* field) { return static_cast<uint32_t>(Bytes<4>(field)); }
  int32_t I32(const char* field) {
    const uint32_t bits = static_cast<uint32_t>(Bytes<4>(field));
    int32_t value;
    std::memcpy(&value, &bits, 4);
    return value;
  }
  uint8_t U8(const char* field) { return static_cast<uint8_t>(Bytes<1>(field)); }
  double F64(const char* field) {
    const uint64_t bits = Bytes<8>(field);
    double value;
    std::memcpy(&value, &bits, 8);
    return value;
  }
  double FiniteF64(const char* field) {
    const double value = F64(field);
    if (!std::isfinite(value)) Fail(field, "is not finite");
    return value;
  }
  // Bytes up to (not including) the next NUL.
  std::string NulTerminated(const char* field) {
    std::string text;
    for (;;) {
      if (Remaining() == 0) Fail(field, "file ends before the name's terminating NUL byte");
      const char c = static_cast<char>(Bytes<1>(field));
      if (c == '\0') return text;
      text += c;
    }
  }

  void ExpectEnd() const {
    if (Remaining() != 0) {
      std::string message = path_ + ": " + std::to_string(Remaining()) +
                            " unexpected bytes after the last entry (at offset " +
                            std::to_string(offset_) + "; damaged or not a COLMAP file)";
      ThrowInvalid(message);
    }
  }

 private:
  // Reads N bytes as a little-endian unsigned integer.
  template <int N>
  uint64_t Bytes(const char* field) {
    if (Remaining() < N) {
      Fail(field, "file ends early (needs " + std::to_string(N) + " bytes at offset " +
                      std::to_string(offset_) + ", file size " + std::to_string(size_) + ")");
    }
    uint64_t value = 0;
    for (int i = 0; i < N; ++i) {
      if (position_ == buffer_.size()) Refill();
      value |= static_cast<uint64_t>(static_cast<unsigned char>(buffer_[position_++])) << (8 * i);
    }
    offset_ += N;
    return value;
  }
  void Refill() {
    constexpr uint64_t kChunk = 1 << 20;
    const uint64_t n = std::min<uint64_t>(kChunk, size_ - file_offset_);
    buffer_.resize(n);
    file_.read(buffer_.data(), static_cast<std::streamsize>(n));
    if (static_cast<uint64_t>(file_.gcount()) != n) {
      ThrowInvalid(path_ + ": read error at offset " + std::to_string(file_offset_));
    }
    file_offset_ += n;
    position_ = 0;
  }

  std::string path_;
  ProgressSink* progress_ = nullptr;  // polled for cancellation every 4096 entries
  std::ifstream file_;
  uint64_t size_ = 0;
  uint64_t offset_ = 0;       // bytes consumed
  uint64_t file_offset_ = 0;  // bytes read into buffers
  std::vector<char> buffer_;
  size_t position_ = 0;
  const char* kind_ = nullptr;
  uint64_t index_ = 0, count_ = 0, id_ = 0;
  bool has_id_ = false;
};

void ReadCamerasBinary(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  BinaryReader reader(path, progress);
  const uint64_t count = reader.U64("number of cameras");
  // id, model id, width, height (the parameters come on top).
  reader.CheckCount(count, 4 + 4 + 8 + 8, "number of cameras");
  model->cameras.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    reader.SetEntry("camera", i, count);
    ColmapCamera camera;
    camera.camera_id = reader.U32("camera_id");
    reader.SetId(camera.camera_id);
    const int32_t model_id = reader.I32("model_id");
    camera.model = ColmapModelName(model_id);
    if (camera.model.empty()) {
      reader.Fail("model_id", "unknown COLMAP camera model id " + std::to_string(model_id) +
                                  " (known: 0.." + std::to_string(kNumModels - 1) + ")");
    }
    camera.width = SideFrom(reader.U64("width"), "width", reader.Failer());
    camera.height = SideFrom(reader.U64("height"), "height", reader.Failer());
    const int num_params = kModels[model_id].num_params;
    for (int k = 0; k < num_params; ++k) {
      const std::string field = "params[" + std::to_string(k) + "]";
      camera.params.push_back(reader.FiniteF64(field.c_str()));
    }
    model->cameras.push_back(std::move(camera));
  }
  reader.ExpectEnd();
}

void ReadImagesBinary(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  BinaryReader reader(path, progress);
  const uint64_t count = reader.U64("number of images");
  // id, qvec, tvec, camera id, the name's NUL, num points2D.
  reader.CheckCount(count, 4 + 56 + 4 + 1 + 8, "number of images");
  model->images.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    reader.SetEntry("image", i, count);
    ColmapImage image;
    image.image_id = reader.U32("image_id");
    reader.SetId(image.image_id);
    std::array<double, 4> qvec{};
    Vec3d tvec(0.0);
    for (double& value : qvec) value = reader.F64("qvec");
    for (int k = 0; k < 3; ++k) tvec[k] = reader.F64("tvec");
    image.cam_from_world = PoseFrom(qvec, tvec, reader.Failer());
    image.camera_id = reader.U32("camera_id");
    image.name = reader.NulTerminated("name");
    const uint64_t num_points2d = reader.U64("num_points2D");
    reader.CheckCount(num_points2d, 8 + 8 + 8, "num_points2D");
    image.num_points2d = num_points2d;
    for (uint64_t k = 0; k < num_points2d; ++k) {
      reader.FiniteF64("points2D.x");
      reader.FiniteF64("points2D.y");
      if (reader.U64("points2D.point3D_id") != kNoPoint3D) ++image.num_observations;
    }
    model->images.push_back(std::move(image));
  }
  reader.ExpectEnd();
}

void ReadPointsBinary(const std::string& path, ColmapModel* model, ProgressSink* progress) {
  BinaryReader reader(path, progress);
  const uint64_t count = reader.U64("number of points");
  // id, xyz, rgb, error, track length.
  reader.CheckCount(count, 8 + 24 + 3 + 8 + 8, "number of points");
  model->points.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    reader.SetEntry("point", i, count);
    ColmapPoint point;
    point.point_id = reader.U64("point3D_id");
    reader.SetId(point.point_id);
    for (int k = 0; k < 3; ++k) point.position[k] = reader.FiniteF64("xyz");
    for (int k = 0; k < 3; ++k) point.color[k] = reader.U8("rgb");
    point.error_px = reader.FiniteF64("error");
    const uint64_t track_length = reader.U64("track_length");
    reader.CheckCount(track_length, 4 + 4, "track_length");
    point.track_length = track_length;
    for (uint64_t k = 0; k < track_length; ++k) {
      reader.U32("track.image_id");
      reader.U32("track.point2D_idx");
    }
    model->points.push_back(point);
  }
  reader.ExpectEnd();
}

// ---------------------------------------------------------------------------------------------
// Whole-model checks and statistics.

void Finish(ColmapModel* model) {
  std::unordered_set<uint32_t> camera_ids;
  for (const ColmapCamera& camera : model->cameras) {
    if (!camera_ids.insert(camera.camera_id).second) {
      ThrowInvalid(model->cameras_path + ": camera " + std::to_string(camera.camera_id) +
                   ": camera_id: listed twice");
    }
  }
  std::unordered_set<uint32_t> image_ids;
  std::unordered_set<std::string> names;
  for (const ColmapImage& image : model->images) {
    const std::string label = model->images_path + ": image " + std::to_string(image.image_id) +
                              " (" + image.name + ")";
    if (!image_ids.insert(image.image_id).second) ThrowInvalid(label + ": image_id: listed twice");
    if (image.name.empty()) ThrowInvalid(label + ": name: is empty");
    if (!IsValidUtf8(image.name)) ThrowInvalid(label + ": name: is not valid UTF-8");
    if (!names.insert(image.name).second) ThrowInvalid(label + ": name: listed twice");
    if (camera_ids.count(image.camera_id) == 0) {
      ThrowInvalid(label + ": camera_id: camera " + std::to_string(image.camera_id) +
                   " is not in " + model->cameras_path);
    }
    model->num_observations += image.num_observations;
  }
  std::unordered_set<uint64_t> point_ids;
  point_ids.reserve(model->points.size());
  double error_sum = 0.0;
  size_t num_errors = 0;
  for (const ColmapPoint& point : model->points) {
    if (!point_ids.insert(point.point_id).second) {
      ThrowInvalid(model->points_path + ": point " + std::to_string(point.point_id) +
                   ": point3D_id: listed twice");
    }
    if (point.error_px != -1.0) {
      error_sum += point.error_px;
      ++num_errors;
    }
  }
  model->mean_reprojection_error_px = num_errors == 0 ? 0.0 : error_sum / num_errors;
}

// Subfolders of `folder` that hold a COLMAP model (for the hint when `folder` itself has none).
std::vector<std::string> ModelSubfolders(const std::string& folder) {
  std::vector<std::string> found;
  std::error_code error;
  for (fs::directory_iterator it(folder, error), end; !error && it != end; it.increment(error)) {
    std::error_code ignored;
    if (!it->is_directory(ignored)) continue;
    if (IsFile(it->path() / "cameras.bin") || IsFile(it->path() / "cameras.txt")) {
      found.push_back(it->path().string());
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

// ---------------------------------------------------------------------------------------------
// Import.

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

std::vector<std::string> ListFrameFiles(const std::string& folder) {
  std::error_code error;
  if (!fs::is_directory(folder, error)) ThrowInvalid(folder + ": not a folder");
  const fs::path root(folder);
  std::vector<std::string> frames;
  for (fs::recursive_directory_iterator it(root, fs::directory_options::skip_permission_denied,
                                           error),
       end;
       !error && it != end; it.increment(error)) {
    std::error_code ignored;
    if (!it->is_regular_file(ignored)) continue;
    const std::string extension = Lower(it->path().extension().string());
    if (std::find(std::begin(kFrameExtensions), std::end(kFrameExtensions), extension) ==
        std::end(kFrameExtensions)) {
      continue;
    }
    frames.push_back(it->path().lexically_relative(root).generic_string());
  }
  if (error) ThrowInvalid(folder + ": cannot list the folder (" + error.message() + ")");
  SortNaturally(&frames);
  return frames;
}

const ColmapCamera* ColmapModel::FindCamera(uint32_t camera_id) const {
  for (const ColmapCamera& camera : cameras) {
    if (camera.camera_id == camera_id) return &camera;
  }
  return nullptr;
}

std::string ColmapModelName(int model_id) {
  return model_id >= 0 && model_id < kNumModels ? kModels[model_id].name : "";
}

int ColmapModelNumParams(const std::string& model_name) {
  for (const ModelInfo& info : kModels) {
    if (model_name == info.name) return info.num_params;
  }
  return -1;
}

ColmapModel ReadColmapModel(const std::string& folder, ProgressSink* progress) {
  std::error_code error;
  if (!fs::is_directory(folder, error)) {
    ThrowInvalid(folder + ": COLMAP model folder does not exist");
  }
  const fs::path root(folder);
  const char* names[] = {"cameras", "images", "points3D"};
  auto all_exist = [&](const char* extension) {
    for (const char* name : names) {
      if (!IsFile(root / (std::string(name) + extension))) return false;
    }
    return true;
  };
  ColmapModel model;
  model.folder = folder;
  const char* extension = nullptr;
  if (all_exist(".bin")) {
    model.format = "binary";
    extension = ".bin";
  } else if (all_exist(".txt")) {
    model.format = "text";
    extension = ".txt";
  } else {
    std::string found;
    for (const char* ext : {".bin", ".txt"}) {
      for (const char* name : names) {
        if (IsFile(root / (std::string(name) + ext))) {
          found += (found.empty() ? "" : ", ") + std::string(name) + ext;
        }
      }
    }
    std::string message = folder + ": not a COLMAP sparse model: needs cameras, images and "
                                   "points3D, all .bin or all .txt (found " +
                          (found.empty() ? std::string("none") : found) + ")";
    const auto subfolders = ModelSubfolders(folder);
    if (!subfolders.empty()) {
      message += "; COLMAP writes each model into a numbered subfolder: ";
      for (size_t i = 0; i < subfolders.size() && i < 5; ++i) {
        message += (i ? ", " : "") + subfolders[i];
      }
    }
    ThrowInvalid(message);
  }
  model.cameras_path = (root / (std::string("cameras") + extension)).string();
  model.images_path = (root / (std::string("images") + extension)).string();
  model.points_path = (root / (std::string("points3D") + extension)).string();
  if (model.format == "binary") {
    ReadCamerasBinary(model.cameras_path, &model, progress);
    ReadImagesBinary(model.images_path, &model, progress);
    ReadPointsBinary(model.points_path, &model, progress);
  } else {
    ReadCamerasText(model.cameras_path, &model, progress);
    ReadImagesText(model.images_path, &model, progress);
    ReadPointsText(model.points_path, &model, progress);
  }
  Finish(&model);
  return model;
}

LensCamera LensFromColmapCamera(const ColmapCamera& camera, const std::string& where) {
  const std::string label =
      Where(where, "camera " + std::to_string(camera.camera_id) + " (" + camera.model + ")");
  const int num_params = ColmapModelNumParams(camera.model);
  if (num_params < 0) ThrowInvalid(label + ": model: unknown COLMAP camera model");
  if (camera.params.size() != static_cast<size_t>(num_params)) {
    ThrowInvalid(label + ": params: the model has " + std::to_string(num_params) +
                 " parameters, got " + std::to_string(camera.params.size()));
  }
  for (size_t i = 0; i < camera.params.size(); ++i) {
    if (!std::isfinite(camera.params[i])) {
      ThrowInvalid(label + ": params[" + std::to_string(i) + "]: is not finite");
    }
  }
  const std::vector<double>& p = camera.params;
  const std::string& m = camera.model;
  LensCamera lens;
  lens.width = camera.width;
  lens.height = camera.height;
  // One focal length (f, cx, cy, ...) or two (fx, fy, cx, cy, ...).
  auto set_intrinsics = [&](bool single_focal) {
    if (single_focal) {
      lens.fx = lens.fy = p[0];
      lens.cx = p[1];
      lens.cy = p[2];
    } else {
      lens.fx = p[0];
      lens.fy = p[1];
      lens.cx = p[2];
      lens.cy = p[3];
    }
  };
  if (m == "SIMPLE_PINHOLE" || m == "PINHOLE") {
    set_intrinsics(m == "SIMPLE_PINHOLE");
    lens.model = LensModel::kPinhole;
  } else if (m == "SIMPLE_RADIAL" || m == "RADIAL" || m == "OPENCV" || m == "FULL_OPENCV") {
    if (m == "FULL_OPENCV") {
      const char* names[] = {"k4", "k5", "k6"};
      for (int k = 0; k < 3; ++k) {
        if (p[9 + k] != 0.0) {
          ThrowInvalid(label + ": params[" + std::to_string(9 + k) + "] (" + names[k] + " = " +
                       FormatNumber(p[9 + k]) +
                       "): the rational radial distortion (k4, k5, k6) is not supported by aos; "
                       "only k4 = k5 = k6 = 0 maps to the radtan lens");
        }
      }
    }
    set_intrinsics(m == "SIMPLE_RADIAL" || m == "RADIAL");
    // aos radtan distortion = {k1, k2, p1, p2, k3}.
    if (m == "SIMPLE_RADIAL") {
      lens.distortion = {p[3], 0, 0, 0, 0};
    } else if (m == "RADIAL") {
      lens.distortion = {p[3], p[4], 0, 0, 0};
    } else if (m == "OPENCV") {
      lens.distortion = {p[4], p[5], p[6], p[7], 0};
    } else {
      lens.distortion = {p[4], p[5], p[6], p[7], p[8]};
    }
    const bool distorted = std::any_of(lens.distortion.begin(), lens.distortion.end(),
                                       [](double k) { return k != 0.0; });
    lens.model = distorted ? LensModel::kRadTan : LensModel::kPinhole;
  } else if (m == "OPENCV_FISHEYE" || m == "SIMPLE_RADIAL_FISHEYE" || m == "RADIAL_FISHEYE" ||
             m == "SIMPLE_FISHEYE" || m == "FISHEYE") {
    const bool single_focal =
        m == "SIMPLE_RADIAL_FISHEYE" || m == "RADIAL_FISHEYE" || m == "SIMPLE_FISHEYE";
    set_intrinsics(single_focal);
    // aos fisheye distortion = {k1, k2, k3, k4, 0}.
    if (m == "OPENCV_FISHEYE") {
      lens.distortion = {p[4], p[5], p[6], p[7], 0};
    } else if (m == "SIMPLE_RADIAL_FISHEYE") {
      lens.distortion = {p[3], 0, 0, 0, 0};
    } else if (m == "RADIAL_FISHEYE") {
      lens.distortion = {p[3], p[4], 0, 0, 0};
    }
    lens.model = LensModel::kFisheye;
  } else {
    ThrowInvalid(label + ": model: COLMAP's " + m +
                 " model has no aos lens (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, "
                 "RADIAL, OPENCV, FULL_OPENCV with k4 = k5 = k6 = 0, OPENCV_FISHEYE, "
                 "SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE, SIMPLE_FISHEYE, FISHEYE); undistort the "
                 "images with COLMAP (image_undistorter) or recalibrate with a supported model");
  }
  lens.Finalize(label);
  return lens;
}

FrameOrder CaptureTimeOrder(const std::vector<std::string>& frames,
                            const std::vector<std::optional<double>>& times,
                            const std::string& time_source) {
  FrameOrder result;
  result.order.resize(frames.size());
  for (size_t i = 0; i < result.order.size(); ++i) result.order[i] = i;
  size_t timed = 0, untimed = frames.size();
  for (size_t i = 0; i < times.size(); ++i) {
    if (times[i]) {
      ++timed;
    } else if (untimed == frames.size()) {
      untimed = i;
    }
  }
  if (timed == 0) return result;
  if (timed < frames.size()) {
    result.warnings.push_back(
        std::to_string(frames.size() - timed) + " of " + std::to_string(frames.size()) +
        " frames have no capture time (" + time_source + "; e.g. " + frames[untimed] +
        "): the views follow the frames' names in natural order (2 before 10) instead");
    return result;
  }
  std::vector<size_t>& order = result.order;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return *times[a] < *times[b]; });
  result.by = "time";
  result.time_source = time_source;
  size_t moved = 0;
  for (size_t i = 0; i < order.size(); ++i) moved += order[i] != i ? 1 : 0;
  for (size_t i = 0; i < order.size(); ++i) {
    if (order[i] == i) continue;
    const double t0 = *times[order.front()];
    result.warnings.push_back(
        "the frames' name order and capture-time order disagree (" + std::to_string(moved) +
        " of " + std::to_string(frames.size()) + " frames move): " + frames[order[i]] +
        " (at +" + FormatNumber(*times[order[i]] - t0) + " s) was taken before " + frames[i] +
        " (at +" + FormatNumber(*times[i] - t0) + " s); the views follow capture time (" +
        time_source + ")");
    break;
  }
  return result;
}

void ColmapImportOptions::Check() const {
  CheckThreadCount(num_threads);
}

ColmapImport ImportColmapModel(const ColmapModel& model, const std::string& images_dir,
                               const ColmapImportOptions& options, ProgressSink* progress) {
  options.Check();
  const std::string source = model.images_path.empty() ? std::string("COLMAP model")
                                                       : model.images_path;
  if (model.images.empty()) ThrowInvalid(source + ": the model has no registered images");
  std::error_code error;
  if (!fs::is_directory(images_dir, error)) {
    ThrowInvalid(images_dir + ": images_dir: folder does not exist");
  }
  const std::string cameras_source = model.cameras_path.empty() ? std::string("COLMAP model")
                                                                : model.cameras_path;

  // Views in natural name order (file_util.h: 2.png before 10.png); lenses made once per camera
  // used.
  std::vector<const ColmapImage*> images;
  for (const ColmapImage& image : model.images) images.push_back(&image);
  std::sort(images.begin(), images.end(), [](const ColmapImage* a, const ColmapImage* b) {
    return NaturalLess(a->name, b->name);
  });
  ColmapImport result;
  // Capture-time order where every frame has one (headers only; a missing frame is reported
  // below with its image).
  {
    std::vector<std::string> names;
    std::vector<std::optional<double>> times;
    std::vector<std::string> bad_times;
    ProgressStart(progress, "times", static_cast<int64_t>(images.size()));
    for (const ColmapImage* image : images) {
      if (ProgressCancelled(progress)) throw Cancelled();
      ProgressAdvance(progress, 1);
      names.push_back(image->name);
      const std::string path = (fs::path(images_dir) / image->name).string();
      std::optional<double> time;
      try {
        if (IsFile(path)) time = ReadCaptureTime(path);
      } catch (const std::invalid_argument& error) {
        // COLMAP does not need the time: a malformed tag costs the time order, not the import.
        bad_times.push_back(error.what());
      }
      times.push_back(time);
    }
    FrameOrder order = CaptureTimeOrder(names, times, "EXIF DateTimeOriginal");
    if (!bad_times.empty()) {
      order.warnings.insert(order.warnings.begin(),
                            std::to_string(bad_times.size()) + " frame" +
                                (bad_times.size() == 1 ? " has" : "s have") +
                                " an unreadable capture time, taken as none: " + bad_times.front());
    }
    std::vector<const ColmapImage*> ordered;
    for (size_t k : order.order) ordered.push_back(images[k]);
    images.swap(ordered);
    result.order = order.by;
    result.time_source = order.time_source;
    result.warnings = std::move(order.warnings);
  }
  std::map<uint32_t, LensCamera> lenses;
  std::vector<std::string> labels;
  for (const ColmapImage* image : images) {
    const std::string label =
        source + ": image " + std::to_string(image->image_id) + " (" + image->name + ")";
    auto lens = lenses.find(image->camera_id);
    if (lens == lenses.end()) {
      const ColmapCamera* camera = model.FindCamera(image->camera_id);
      if (camera == nullptr) {
        ThrowInvalid(label + ": camera_id: camera " + std::to_string(image->camera_id) +
                     " is not in the model");
      }
      lens = lenses.emplace(image->camera_id, LensFromColmapCamera(*camera, cameras_source))
                 .first;
    }
    if (auto problem = DescribeInvalidRigid(image->cam_from_world)) {
      ThrowInvalid(label + ": cam_from_world: " + *problem);
    }
    View view;
    view.name = image->name;
    view.image_path = (fs::path(images_dir) / image->name).string();
    if (!IsFile(view.image_path)) {
      ThrowInvalid(label + ": frame " + Quoted(view.image_path) + " not found in images_dir");
    }
    view.camera = lens->second;
    view.cam_from_world = image->cam_from_world;
    result.light_field.views.push_back(std::move(view));
    result.registered.push_back(image->name);
    labels.push_back(label);
  }

  // Decode (or probe) the frames in parallel; the error of the lowest failing index is reported.
  std::vector<View>& views = result.light_field.views;
  const int64_t n = static_cast<int64_t>(views.size());
  std::vector<ImageFileInfo> infos(views.size());
  ProgressStart(progress, "load", n);
  ParallelFor(n, options.num_threads, progress, [&](int64_t i) {
    View& view = views[i];
    ImageFileInfo& info = infos[i];
    try {
      if (options.load_images) {
        Image image = ReadImage(view.image_path, 1);
        if (auto problem = DescribeNonFinite(image)) ThrowInvalid(*problem);
        info = ImageFileInfo{image.width(), image.height(), image.channels(), image.type()};
        view.image = std::move(image);
      } else {
        info = ReadImageInfo(view.image_path);
      }
    } catch (const std::invalid_argument& problem) {
      ThrowInvalid(labels[i] + ": " + problem.what());
    }
    if (info.width != view.camera.width || info.height != view.camera.height) {
      ThrowInvalid(labels[i] + ": frame " + view.image_path + " is " +
                   SizeText(info.width, info.height) + " but its COLMAP camera in " +
                   cameras_source + " says " +
                   SizeText(view.camera.width, view.camera.height));
    }
  });
  for (size_t i = 0; i < infos.size(); ++i) {
    if (infos[i].channels != infos[0].channels) {
      ThrowInvalid(labels[i] + ": frame has " + std::to_string(infos[i].channels) +
                   " channels but " + result.registered[0] + " has " +
                   std::to_string(infos[0].channels));
    }
  }
  if (options.load_images) CheckLightField(result.light_field, source);

  const std::unordered_set<std::string> registered(result.registered.begin(),
                                                   result.registered.end());
  for (const std::string& frame : ListFrameFiles(images_dir)) {
    if (registered.count(frame) == 0) result.unregistered.push_back(frame);
  }
  return result;
}

}  // namespace aos
