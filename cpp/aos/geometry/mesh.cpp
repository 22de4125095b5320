#include "aos/geometry/mesh.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/memory.h"

namespace aos {
namespace {

// Largest mesh file read: 4 GiB (the whole file is held in memory while parsing).
constexpr uint64_t kMaxMeshFileBytes = uint64_t{4} << 30;

std::string ReadBytes(const std::string& path) {
  const uint64_t size = CheckRegularFile(path, "mesh");
  if (size > kMaxMeshFileBytes) {
    ThrowInvalid(path + ": mesh: the file has " + std::to_string(size) +
                 " bytes, more than the 4 GiB a mesh may have");
  }
  CheckMemoryBudget(size, path + ": mesh: a file of " + std::to_string(size) + " bytes",
                    "the whole file is held while it is parsed");
  std::ifstream stream(path, std::ios::binary);
  if (!stream) ThrowInvalid(path + ": mesh: cannot open the file");
  std::string bytes(static_cast<size_t>(size), '\0');
  stream.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<uint64_t>(stream.gcount()) != size) {
    ThrowInvalid(path + ": mesh: cannot read the file");
  }
  return bytes;
}

bool ParseDouble(const std::string& token, double& value) {
  if (token.empty()) return false;
  const char* begin = token.c_str();
  char* end = nullptr;
  value = std::strtod(begin, &end);
  return end == begin + token.size();
}

bool ParseInt(const std::string& token, long long& value) {
  if (token.empty()) return false;
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  value = std::strtoll(begin, &end, 10);
  return end == begin + token.size() && errno == 0;
}

// Appends the fan triangulation of `corners` (vertex indices, 0-based) to `mesh`.
void AddPolygon(const std::vector<int>& corners, Mesh& mesh) {
  for (size_t k = 1; k + 1 < corners.size(); ++k) {
    mesh.triangles.push_back({corners[0], corners[k], corners[k + 1]});
  }
}

// Bytes of a vertex and of a triangle once read (what a mesh's size is budgeted by).
constexpr uint64_t kVertexBytes = sizeof(Vec3d);
constexpr uint64_t kTriangleBytes = sizeof(std::array<int, 3>);

uint64_t SaturatingSum(uint64_t a, uint64_t b) {
  return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max() : a + b;
}

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// The vertices (`v` lines) and triangles (corners - 2 of each `f` line) of an OBJ file, counted
// without parsing a number: what ReadObj will allocate, checked before it does.
void CountObj(const std::string& bytes, uint64_t& vertices, uint64_t& triangles) {
  vertices = triangles = 0;
  size_t i = 0;
  const size_t n = bytes.size();
  while (i < n) {
    while (i < n && IsBlank(bytes[i])) ++i;
    const bool is_v = i + 1 < n && bytes[i] == 'v' && IsBlank(bytes[i + 1]);
    const bool is_f = i + 1 < n && bytes[i] == 'f' && IsBlank(bytes[i + 1]);
    if (is_v) ++vertices;
    uint64_t corners = 0;
    if (is_f) ++i;
    while (i < n && bytes[i] != '\n') {
      if (is_f && !IsBlank(bytes[i]) && IsBlank(bytes[i - 1])) ++corners;
      ++i;
    }
    if (corners > 2) triangles += corners - 2;
    ++i;  // past the newline
  }
}

// A vertex coordinate as read: finite and within kMaxSurfaceCoordinate, else thrown as
// "<where>: <name> <problem>".
double CheckedCoordinate(double value, const std::string& where, const std::string& name) {
  const std::string problem = SurfaceCoordinateProblem(value);
  if (!problem.empty()) ThrowInvalid(where + ": " + name + " " + problem);
  return value;
}

Mesh ReadObj(const std::string& path, const std::string& bytes) {
  Mesh mesh;
  uint64_t vertex_count = 0, triangle_count = 0;
  CountObj(bytes, vertex_count, triangle_count);
  CheckMemoryBudget(SaturatingSum(SaturatingProduct({vertex_count, kVertexBytes}),
                                  SaturatingProduct({triangle_count, kTriangleBytes})),
                    path + ": mesh: " + std::to_string(vertex_count) + " vertices and " +
                        std::to_string(triangle_count) + " triangles",
                    "read from the OBJ file's v and f lines");
  mesh.vertices.reserve(static_cast<size_t>(vertex_count));
  mesh.triangles.reserve(static_cast<size_t>(triangle_count));
  std::string line;
  int64_t line_number = 0;
  std::vector<int> corners;
  size_t line_start = 0;
  while (line_start < bytes.size()) {
    size_t line_end = bytes.find('\n', line_start);
    if (line_end == std::string::npos) line_end = bytes.size();
    line.assign(bytes, line_start, line_end - line_start);
    line_start = line_end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    if (!(words >> keyword)) continue;
    const std::string where = path + ": line " + std::to_string(line_number);
    if (keyword == "v") {
      Vec3d vertex;
      const char* names[3] = {"x", "y", "z"};
      for (int i = 0; i < 3; ++i) {
        std::string token;
        if (!(words >> token)) ThrowInvalid(where + ": v: " + names[i] + " is missing");
        double value = 0.0;
        if (!ParseDouble(token, value)) {
          ThrowInvalid(where + ": v: " + names[i] + " is not a number ('" + token + "')");
        }
        vertex[i] = CheckedCoordinate(value, where + ": v", names[i]);
      }
      mesh.vertices.push_back(vertex);
    } else if (keyword == "f") {
      corners.clear();
      std::string token;
      while (words >> token) {
        const std::string index_text = token.substr(0, token.find('/'));
        long long index = 0;
        if (!ParseInt(index_text, index) || index == 0) {
          ThrowInvalid(where + ": f: corner " + std::to_string(corners.size() + 1) +
                       ": vertex index '" + token + "' is not a non-zero integer");
        }
        const long long count = static_cast<long long>(mesh.vertices.size());
        const long long resolved = index > 0 ? index - 1 : count + index;
        if (resolved < 0 || resolved >= count) {
          ThrowInvalid(where + ": f: corner " + std::to_string(corners.size() + 1) +
                       ": vertex index " + index_text + " is out of range (" +
                       std::to_string(count) + " vertices read so far)");
        }
        corners.push_back(static_cast<int>(resolved));
      }
      if (corners.size() < 3) {
        ThrowInvalid(where + ": f: a face needs at least 3 corners (got " +
                     std::to_string(corners.size()) + ")");
      }
      AddPolygon(corners, mesh);
    }
  }
  return mesh;
}

// ---- PLY ----

enum class PlyType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

bool PlyTypeFromName(const std::string& name, PlyType& type) {
  static const std::pair<const char*, PlyType> kNames[] = {
      {"char", PlyType::kInt8},     {"int8", PlyType::kInt8},       {"uchar", PlyType::kUInt8},
      {"uint8", PlyType::kUInt8},   {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUInt16}, {"uint16", PlyType::kUInt16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},   {"uint", PlyType::kUInt32},     {"uint32", PlyType::kUInt32},
      {"float", PlyType::kFloat32}, {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (const auto& [text, value] : kNames) {
    if (name == text) {
      type = value;
      return true;
    }
  }
  return false;
}

size_t PlyTypeSize(PlyType type) {
  switch (type) {
    case PlyType::kInt8: case PlyType::kUInt8: return 1;
    case PlyType::kInt16: case PlyType::kUInt16: return 2;
    case PlyType::kInt32: case PlyType::kUInt32: case PlyType::kFloat32: return 4;
    case PlyType::kFloat64: return 8;
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads scalar values from the body, ASCII or binary little endian.
class PlyReader {
 public:
  PlyReader(const std::string& path, const std::string& bytes, size_t offset, bool binary)
      : path_(path), bytes_(bytes), offset_(offset), binary_(binary) {}

  double Read(PlyType type, const std::string& where) {
    if (!binary_) {
      while (offset_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[offset_]))) {
        ++offset_;
      }
      size_t end = offset_;
      while (end < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[end]))) ++end;
      if (end == offset_) ThrowInvalid(where + ": the file ends early (truncated)");
      const std::string token = bytes_.substr(offset_, end - offset_);
      offset_ = end;
      double value = 0.0;
      if (!ParseDouble(token, value)) {
        ThrowInvalid(where + ": '" + token + "' is not a number");
      }
      return value;
    }
    const size_t size = PlyTypeSize(type);
    if (offset_ + size > bytes_.size()) ThrowInvalid(where + ": the file ends early (truncated)");
    const char* p = bytes_.data() + offset_;
    offset_ += size;
    // Little-endian host (x86-64, aarch64): memcpy reads the file's byte order.
    switch (type) {
      case PlyType::kInt8: { int8_t v; std::memcpy(&v, p, 1); return v; }
      case PlyType::kUInt8: { uint8_t v; std::memcpy(&v, p, 1); return v; }
      case PlyType::kInt16: { int16_t v; std::memcpy(&v, p, 2); return v; }
      case PlyType::kUInt16: { uint16_t v; std::memcpy(&v, p, 2); return v; }
      case PlyType::kInt32: { int32_t v; std::memcpy(&v, p, 4); return v; }
      case PlyType::kUInt32: { uint32_t v; std::memcpy(&v, p, 4); return v; }
      case PlyType::kFloat32: { float v; std::memcpy(&v, p, 4); return v; }
      case PlyType::kFloat64: { double v; std::memcpy(&v, p, 8); return v; }
    }
    return 0.0;
  }

 private:
  const std::string& path_;
  const std::string& bytes_;
  size_t offset_;
  bool binary_;
};

// The fewest bytes one item of `element` takes in the body: binary, the sum of its scalar
// properties' sizes and its lists' count sizes (a list may be empty); ASCII, a character and a
// separator per property.
uint64_t PlyElementMinBytes(const PlyElement& element, bool binary) {
  uint64_t bytes = 0;
  for (const PlyProperty& property : element.properties) {
    bytes += binary ? PlyTypeSize(property.is_list ? property.count_type : property.type) : 2;
  }
  return bytes;
}

// The header's counts against the file and the memory budget, before anything is allocated: a
// header may declare 2e9 vertices in a file of a few bytes.
void CheckPlyCounts(const std::string& path, const std::vector<PlyElement>& elements,
                    uint64_t body_bytes, bool binary) {
  // ASCII: the last token needs no separator after it.
  const uint64_t available = binary ? body_bytes : body_bytes + 1;
  uint64_t needed = 0;
  uint64_t vertices = 0, faces = 0;
  for (const PlyElement& element : elements) {
    const uint64_t count = static_cast<uint64_t>(element.count);
    const uint64_t each = PlyElementMinBytes(element, binary);
    needed = SaturatingSum(needed, SaturatingProduct({count, each}));
    if (needed > available) {
      ThrowInvalid(path + ": PLY header: element " + element.name + " " +
                   std::to_string(element.count) + ": the file cannot hold that many (each takes " +
                   "at least " + std::to_string(each) + " bytes " +
                   (binary ? "(binary)" : "(ASCII)") + "; the elements up to it need at least " +
                   std::to_string(needed) + " bytes, the body has " + std::to_string(body_bytes) +
                   ")");
    }
    if (element.name == "vertex") vertices = SaturatingSum(vertices, count);
    if (element.name == "face") faces = SaturatingSum(faces, count);
  }
  // Every face gives at least one triangle (one with fewer than 3 corners is refused).
  CheckMemoryBudget(SaturatingSum(SaturatingProduct({vertices, kVertexBytes}),
                                  SaturatingProduct({faces, kTriangleBytes})),
                    path + ": PLY header: element vertex " + std::to_string(vertices) +
                        ", element face " + std::to_string(faces),
                    "their vertices and triangles");
}

Mesh ReadPly(const std::string& path, const std::string& bytes) {
  // Header: lines up to "end_header".
  size_t offset = 0;
  std::vector<PlyElement> elements;
  bool binary = false, have_format = false, ended = false;
  int line_number = 0;
  while (offset < bytes.size()) {
    size_t end = bytes.find('\n', offset);
    if (end == std::string::npos) end = bytes.size();
    std::string line = bytes.substr(offset, end - offset);
    offset = std::min(bytes.size(), end + 1);
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = path + ": header line " + std::to_string(line_number);
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (line_number == 1) {
      if (keyword != "ply") ThrowInvalid(where + ": a PLY file starts with 'ply'");
      continue;
    }
    if (keyword == "end_header") {
      ended = true;
      break;
    }
    if (keyword == "format") {
      std::string format, version;
      words >> format >> version;
      if (format == "ascii") {
        binary = false;
      } else if (format == "binary_little_endian") {
        binary = true;
      } else {
        ThrowInvalid(where + ": format: '" + format +
                     "' is not supported (ascii or binary_little_endian)");
      }
      have_format = true;
    } else if (keyword == "element") {
      PlyElement element;
      std::string count_text;
      words >> element.name >> count_text;
      long long count = 0;
      if (!ParseInt(count_text, count) || count < 0) {
        ThrowInvalid(where + ": element " + element.name + ": count '" + count_text +
                     "' is not a non-negative integer");
      }
      element.count = count;
      elements.push_back(element);
    } else if (keyword == "property") {
      if (elements.empty()) ThrowInvalid(where + ": property before any element");
      PlyProperty property;
      std::string type_name;
      words >> type_name;
      if (type_name == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type >> property.name;
        property.is_list = true;
        if (!PlyTypeFromName(count_type, property.count_type) ||
            !PlyTypeFromName(item_type, property.type)) {
          ThrowInvalid(where + ": property " + property.name + ": unknown list type '" +
                       count_type + " " + item_type + "'");
        }
      } else {
        words >> property.name;
        if (!PlyTypeFromName(type_name, property.type)) {
          ThrowInvalid(where + ": property " + property.name + ": unknown type '" + type_name +
                       "'");
        }
      }
      elements.back().properties.push_back(property);
    } else if (keyword == "comment" || keyword == "obj_info" || keyword.empty()) {
      continue;
    } else {
      ThrowInvalid(where + ": unknown header keyword '" + keyword + "'");
    }
  }
  if (!ended) ThrowInvalid(path + ": PLY header: no 'end_header' line");
  if (!have_format) ThrowInvalid(path + ": PLY header: no 'format' line");
  CheckPlyCounts(path, elements, bytes.size() - offset, binary);

  Mesh mesh;
  int64_t vertex_count = -1;
  PlyReader reader(path, bytes, offset, binary);
  std::vector<int> corners;
  for (const PlyElement& element : elements) {
    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    int xyz[3] = {-1, -1, -1};
    int index_property = -1;
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      for (int k = 0; k < 3 && is_vertex; ++k) {
        if (property.name == std::string(1, "xyz"[k]) && !property.is_list) xyz[k] = static_cast<int>(p);
      }
      if (is_face && property.is_list &&
          (property.name == "vertex_indices" || property.name == "vertex_index")) {
        index_property = static_cast<int>(p);
      }
    }
    if (is_vertex) {
      for (int k = 0; k < 3; ++k) {
        if (xyz[k] < 0) {
          ThrowInvalid(path + ": element vertex: no property " + std::string(1, "xyz"[k]));
        }
      }
      vertex_count = element.count;
      if (element.count > std::numeric_limits<int>::max()) {
        ThrowInvalid(path + ": element vertex: " + std::to_string(element.count) +
                     " vertices is more than a mesh may have");
      }
      mesh.vertices.reserve(static_cast<size_t>(element.count));
    }
    if (is_face && index_property < 0) {
      ThrowInvalid(path + ": element face: no list property vertex_indices");
    }
    if (is_face) mesh.triangles.reserve(static_cast<size_t>(element.count));
    // An element without properties takes no bytes: nothing to read (and no count to loop on).
    if (element.properties.empty()) continue;
    for (int64_t i = 0; i < element.count; ++i) {
      const std::string where = path + ": element " + element.name + " " + std::to_string(i);
      Vec3d vertex(0.0);
      corners.clear();
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        if (!property.is_list) {
          const double value = reader.Read(property.type, where + ": " + property.name);
          for (int k = 0; k < 3 && is_vertex; ++k) {
            if (xyz[k] == static_cast<int>(p)) {
              vertex[k] = CheckedCoordinate(value, where, property.name);
            }
          }
          continue;
        }
        const double count = reader.Read(property.count_type, where + ": " + property.name);
        if (!(count >= 0.0 && count <= 1e6) || count != std::floor(count)) {
          ThrowInvalid(where + ": " + property.name + ": list length " + FormatNumber(count) +
                       " is not an integer in 0..1000000");
        }
        for (int k = 0; k < static_cast<int>(count); ++k) {
          const double value = reader.Read(property.type, where + ": " + property.name);
          if (is_face && static_cast<int>(p) == index_property) {
            if (vertex_count < 0) {
              ThrowInvalid(where + ": faces come before the vertex element");
            }
            if (!(value >= 0.0 && value < static_cast<double>(vertex_count)) ||
                value != std::floor(value)) {
              ThrowInvalid(where + ": " + property.name + ": index " + FormatNumber(value) +
                           " is out of range (" + std::to_string(vertex_count) + " vertices)");
            }
            corners.push_back(static_cast<int>(value));
          }
        }
      }
      if (is_vertex) mesh.vertices.push_back(vertex);
      if (is_face) {
        if (corners.size() < 3) {
          ThrowInvalid(where + ": " + element.properties[static_cast<size_t>(index_property)].name +
                       ": a face needs at least 3 corners (got " +
                       std::to_string(corners.size()) + ")");
        }
        AddPolygon(corners, mesh);
      }
    }
  }
  return mesh;
}

bool EndsWith(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(text[text.size() - suffix.size() + i])) != suffix[i]) {
      return false;
    }
  }
  return true;
}

}  // namespace

std::string SurfaceCoordinateProblem(double value) {
  if (!std::isfinite(value)) return "is not finite (" + FormatNumber(value) + ")";
  if (std::abs(value) <= kMaxSurfaceCoordinate) return "";
  return "is " + FormatNumber(value) + " m, beyond +-" + FormatNumber(kMaxSurfaceCoordinate) +
         " m, the most a surface coordinate may be (an undeclared nodata value, or a unit "
         "mistake?)";
}

void DropDegenerateTriangles(Mesh& mesh) {
  size_t kept = 0;
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    bool degenerate = t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
    if (!degenerate) {
      const Vec3d& a = mesh.vertices[static_cast<size_t>(t[0])];
      const Vec3d cross = glm::cross(mesh.vertices[static_cast<size_t>(t[1])] - a,
                                     mesh.vertices[static_cast<size_t>(t[2])] - a);
      degenerate = cross.x == 0.0 && cross.y == 0.0 && cross.z == 0.0;
    }
    if (degenerate) {
      ++mesh.dropped_triangles;
    } else {
      mesh.triangles[kept++] = t;
    }
  }
  mesh.triangles.resize(kept);
}

void Mesh::Check(const std::string& where) const {
  if (vertices.empty()) ThrowInvalid(Where(where, "the mesh has no vertices"));
  if (triangles.empty()) {
    ThrowInvalid(Where(where, "the mesh has no triangles" +
                                  (dropped_triangles > 0
                                       ? " (all " + std::to_string(dropped_triangles) +
                                             " were degenerate: repeated vertex or zero area)"
                                       : std::string())));
  }
  for (size_t i = 0; i < vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const std::string problem = SurfaceCoordinateProblem(vertices[i][k]);
      if (!problem.empty()) {
        ThrowInvalid(Where(where, "vertex " + std::to_string(i) + ": " + "xyz"[k] + " " + problem));
      }
    }
  }
  const int64_t count = static_cast<int64_t>(vertices.size());
  for (size_t i = 0; i < triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (triangles[i][k] < 0 || triangles[i][k] >= count) {
        ThrowInvalid(Where(where, "triangle " + std::to_string(i) + ": vertex index " +
                                      std::to_string(triangles[i][k]) + " is out of range (" +
                                      std::to_string(count) + " vertices)"));
      }
    }
  }
}

namespace {

Mesh ParseMeshFile(const std::string& path) {
  const std::string bytes = ReadBytes(path);
  const bool is_ply = bytes.compare(0, 3, "ply") == 0;
  if (!is_ply && !EndsWith(path, ".obj") && EndsWith(path, ".ply")) {
    ThrowInvalid(path + ": mesh: a .ply file must start with 'ply'");
  }
  return is_ply ? ReadPly(path, bytes) : ReadObj(path, bytes);
}

}  // namespace

bool IsMeshFile(const std::string& path) {
  // A FIFO would block the open below forever, a device never ends: regular files only.
  CheckRegularFile(path, "surface or DEM file");
  std::ifstream file(path, std::ios::binary);
  if (!file) ThrowInvalid(path + ": cannot open the file");
  char bytes[3] = {0, 0, 0};
  file.read(bytes, 3);
  return std::string(bytes, static_cast<size_t>(file.gcount())) == "ply" ||
         EndsWith(path, ".obj") || EndsWith(path, ".ply");
}

std::vector<Vec3d> ReadPoints(const std::string& path) {
  Mesh mesh = ParseMeshFile(path);
  if (mesh.vertices.empty()) ThrowInvalid(path + ": the file has no vertices (points)");
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const std::string problem = SurfaceCoordinateProblem(mesh.vertices[i][k]);
      if (!problem.empty()) {
        ThrowInvalid(path + ": vertex " + std::to_string(i) + ": " + "xyz"[k] + " " + problem);
      }
    }
  }
  return std::move(mesh.vertices);
}

void WritePly(const std::string& path, const std::vector<Vec3d>& vertices,
              const std::vector<std::array<int, 3>>& triangles, bool overwrite) {
  if (!overwrite && std::filesystem::exists(path)) {
    ThrowInvalid(path + ": exists (not overwritten)");
  }
  std::string bytes = "ply\nformat binary_little_endian 1.0\ncomment written by aos\nelement vertex " +
                      std::to_string(vertices.size()) +
                      "\nproperty double x\nproperty double y\nproperty double z\n";
  if (!triangles.empty()) {
    bytes += "element face " + std::to_string(triangles.size()) +
             "\nproperty list uchar int vertex_indices\n";
  }
  bytes += "end_header\n";
  static_assert(sizeof(double) == 8 && sizeof(int) == 4, "PLY double/int sizes");
  const size_t header = bytes.size();
  bytes.resize(header + vertices.size() * 24 + triangles.size() * 13);
  char* out = bytes.data() + header;
  for (const Vec3d& v : vertices) {
    const double xyz[3] = {v.x, v.y, v.z};
    std::memcpy(out, xyz, 24);  // little-endian host (x86-64, ARM64 Linux)
    out += 24;
  }
  for (const auto& t : triangles) {
    *out++ = 3;
    std::memcpy(out, t.data(), 12);
    out += 12;
  }
  PendingFile file(path);
  {
    std::ofstream stream(file.TempPath(), std::ios::binary);
    stream.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!stream.good()) ThrowInvalid(path + ": could not write");
  }
  file.Commit();
}

Mesh ReadMesh(const std::string& path) {
  Mesh mesh = ParseMeshFile(path);
  DropDegenerateTriangles(mesh);
  mesh.Check(path);
  return mesh;
}

}  // namespace aos
