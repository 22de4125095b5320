#include "aos/lightfield/formats.h"


#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <map>
#include <system_error>
#include <utility>

#include <nlohmann/json.hpp>

#include "aos/geometry/geodesy.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/json_codec.h"
#include "aos/lightfield/mask.h"
#include "aos/util/error.h"
#include "aos/util/parallel.h"
#include "aos/util/file_util.h"
#include "aos/util/json_file.h"
#include "aos/util/memory.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

using nlohmann::json;

constexpr const char* kAosFormatName = "aos-lightfield";
constexpr int kAosFormatVersion = 1;
// Extensions tried, in this order, when a JKU frame is not found under its own name.
constexpr std::array<const char*, 6> kFrameExtensions = {".png", ".tif",  ".tiff",
                                                         ".jpg", ".jpeg", ".exr"};

std::string Quoted(const std::string& text) { return "\"" + text + "\""; }

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// A JSON value as text for messages (strings without escaping noise, others dumped).
std::string Describe(const json& value) {
  if (value.is_string()) return Quoted(value.get<std::string>());
  std::string text = value.dump();
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return text;
}

// A number given as a JSON number or (when allowed) a numeric string; finite.
double NumberFrom(const json& value, const std::string& where, bool allow_strings) {
  if (value.is_number()) {
    const double number = value.get<double>();
    if (!std::isfinite(number)) ThrowInvalid(Where(where, "is not a finite number"));
    return number;
  }
  if (value.is_string() && allow_strings) return ParseNumberText(value.get<std::string>(), where);
  ThrowInvalid(Where(where, std::string("expected a number") +
                                (allow_strings ? " or a numeric string" : "") + ", got " +
                                Describe(value)));
}

const json& Field(const json& object, const char* name, const std::string& where) {
  auto it = object.find(name);
  if (it == object.end()) ThrowInvalid(Where(where, std::string(name) + ": missing"));
  return *it;
}

std::string StringFrom(const json& value, const std::string& where) {
  if (!value.is_string()) ThrowInvalid(Where(where, "expected a string, got " + Describe(value)));
  std::string text = value.get<std::string>();
  if (text.empty()) ThrowInvalid(Where(where, "is empty"));
  return text;
}

// `value` must be an array of `size` numbers.
template <size_t N>
std::array<double, N> NumbersFrom(const json& value, const std::string& where, bool allow_strings) {
  if (!value.is_array() || value.size() != N) {
    ThrowInvalid(Where(where, "expected " + std::to_string(N) + " numbers, got " +
                                  Describe(value)));
  }
  std::array<double, N> numbers{};
  for (size_t i = 0; i < N; ++i) {
    numbers[i] = NumberFrom(value[i], where + "[" + std::to_string(i) + "]", allow_strings);
  }
  return numbers;
}

// Checks a pose read from a file; `where` names the entry and the field.
void CheckPose(const Rigid3d& pose, const std::string& where) {
  if (auto problem = DescribeInvalidRigid(pose)) ThrowInvalid(Where(where, *problem));
}

std::string ParentFolder(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

// Resolves `name` against `folder` unless it is absolute.
std::string ResolvePath(const std::string& folder, const std::string& name) {
  const fs::path path(name);
  if (path.is_absolute()) return path.string();
  if (folder == ".") return path.string();
  return (fs::path(folder) / path).string();
}

bool IsFile(const std::string& path) {
  std::error_code error;
  return fs::is_regular_file(path, error);
}

// Files of folders listed once, by lower-case name: the frame lookup's case-insensitive fallback
// (a poses file naming a.jpg for the camera's A.JPG) without listing a folder per frame.
class FolderIndex {
 public:
  // The files in `path`'s folder whose names equal `path`'s file name ignoring case (full paths,
  // sorted); empty when the folder cannot be listed.
  std::vector<std::string> MatchesIgnoringCase(const std::string& path) {
    const fs::path file(path);
    const std::string folder = file.parent_path().string();
    auto listed = folders_.find(folder);
    if (listed == folders_.end()) {
      std::map<std::string, std::vector<std::string>> names;
      std::error_code error;
      for (fs::directory_iterator it(folder.empty() ? fs::path(".") : fs::path(folder), error), end;
           !error && it != end; it.increment(error)) {
        std::error_code type_error;
        if (!it->is_regular_file(type_error)) continue;
        const std::string name = it->path().filename().string();
        names[Lower(name)].push_back(name);
      }
      for (auto& [unused, entries] : names) std::sort(entries.begin(), entries.end());
      listed = folders_.emplace(folder, std::move(names)).first;
    }
    std::vector<std::string> matches;
    auto found = listed->second.find(Lower(file.filename().string()));
    if (found == listed->second.end()) return matches;
    for (const std::string& name : found->second) {
      matches.push_back(folder.empty() ? name : (fs::path(folder) / name).string());
    }
    return matches;
  }

 private:
  std::map<std::string, std::map<std::string, std::vector<std::string>>> folders_;
};

// `path` itself if it is a file; else the one file whose name matches it ignoring case ("" if
// none). Two or more such files are ambiguous: an error `label: field: ...` naming them.
std::string FindFrameFile(const std::string& path, FolderIndex& index, const std::string& label,
                          const std::string& field) {
  if (IsFile(path)) return path;
  const std::vector<std::string> matches = index.MatchesIgnoringCase(path);
  if (matches.size() > 1) {
    ThrowInvalid(Where(label, field + ": " + Quoted(fs::path(path).filename().string()) +
                                  " is missing and " + std::to_string(matches.size()) +
                                  " files match it ignoring case (" + Quoted(matches[0]) +
                                  ", " + Quoted(matches[1]) +
                                  (matches.size() > 2 ? ", ..." : "") +
                                  "); rename one or name the frame exactly"));
  }
  return matches.empty() ? std::string() : matches[0];
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// One frame to decode (or probe) and where it came from, for messages.
struct Frame {
  std::string label;  // "file: view 3 (a.png)" / "file: image 3 (a.tiff)"
  std::string path;   // resolved file
};

struct FrameData {
  std::vector<Image> images;          // when decoding
  std::vector<ImageFileInfo> infos;   // always
  std::vector<int64_t> valid_pixels;  // masked: valid pixels of each frame's mask
};

// The masks of the frames (LoadOptions::mask or mask_dir), resolved before decoding.
struct FrameMasks {
  bool enabled = false;
  Image shared;                     // mask: the valid pixels of the one mask
  std::string shared_path;
  std::vector<std::string> paths;   // mask_dir: each frame's mask file
};

// The frames' masks: the one mask read once, or each frame's file found in mask_dir by the
// frame's file name without its extension (any image extension, case ignored).
FrameMasks ResolveMasks(const std::vector<Frame>& frames, const LoadOptions& options) {
  FrameMasks masks;
  if (!options.mask.empty()) {
    masks.enabled = true;
    masks.shared_path = options.mask;
    masks.shared = ReadMask(options.mask);
    return masks;
  }
  if (options.mask_dir.empty()) return masks;
  masks.enabled = true;
  std::error_code error;
  if (!fs::is_directory(options.mask_dir, error)) {
    ThrowInvalid("mask_dir: folder " + Quoted(options.mask_dir) + " does not exist");
  }
  // Image files of the folder by lower-case stem.
  std::map<std::string, std::vector<std::string>> by_stem;
  for (fs::directory_iterator it(options.mask_dir, error), end; !error && it != end;
       it.increment(error)) {
    std::error_code type_error;
    if (!it->is_regular_file(type_error)) continue;
    const std::string extension = Lower(it->path().extension().string());
    if (std::find(kFrameExtensions.begin(), kFrameExtensions.end(), extension) ==
        kFrameExtensions.end()) {
      continue;
    }
    by_stem[Lower(it->path().stem().string())].push_back(it->path().string());
  }
  for (const Frame& frame : frames) {
    const std::string stem = fs::path(frame.path).stem().string();
    auto found = by_stem.find(Lower(stem));
    if (found == by_stem.end()) {
      ThrowInvalid(Where(frame.label, "mask_dir: no mask for this frame in " +
                                          Quoted(options.mask_dir) + " (looked for " + stem +
                                          ".png, .tif, .tiff, .jpg, .jpeg or .exr, case ignored)"));
    }
    std::vector<std::string>& candidates = found->second;
    if (candidates.size() > 1) {
      std::sort(candidates.begin(), candidates.end());
      ThrowInvalid(Where(frame.label, "mask_dir: " + std::to_string(candidates.size()) +
                                          " masks match this frame (" + Quoted(candidates[0]) +
                                          ", " + Quoted(candidates[1]) +
                                          "); keep one per frame"));
    }
    masks.paths.push_back(candidates[0]);
  }
  return masks;
}

// Decodes (load_images) or probes the frames in parallel.
FrameData ReadFrames(const std::vector<Frame>& frames, const LoadOptions& options,
                     ProgressSink* progress, const FrameMasks& masks = {}) {
  const int64_t n = static_cast<int64_t>(frames.size());
  FrameData data;
  data.infos.resize(frames.size());
  if (options.load_images) data.images.resize(frames.size());
  if (masks.enabled) data.valid_pixels.resize(frames.size(), 0);
  if (options.load_images && n > 0) {
    // Refuse a light field the machine cannot hold before decoding any of it (estimated from the
    // first frame's header; every frame's own header is checked again as it is decoded).
    ImageFileInfo first;
    try {
      first = ReadImageInfo(frames[0].path);
    } catch (const std::invalid_argument& error) {
      ThrowInvalid(Where(frames[0].label, error.what()));
    }
    CheckMemoryBudget(
        SaturatingProduct({static_cast<uint64_t>(n), static_cast<uint64_t>(first.width) + 2,
                           static_cast<uint64_t>(first.height) + 2,
                           static_cast<uint64_t>(first.channels) + (masks.enabled ? 1 : 0),
                           PixelTypeSize(first.type)}),
        frames[0].label + ": light field of " + std::to_string(n) + " frames of " +
            SizeText(first.width, first.height),
        "the decoded frames, estimated from the first frame's header");
  }
  ProgressStart(progress, "load", n);
  ParallelFor(n, options.num_threads, progress, [&](int64_t i) {
    const Frame& frame = frames[i];
    try {
      ImageFileInfo& info = data.infos[i];
      if (options.load_images) {
        Image image = ReadImage(frame.path, 1);  // refuses non-finite samples
        if (options.grey) image = LuminanceImage(image);
        if (masks.enabled) {
          const bool shared = masks.paths.empty();
          const Image valid = shared ? masks.shared : ReadMask(masks.paths[i]);
          image = ApplyMask(image, valid, shared ? masks.shared_path : masks.paths[i], "");
          data.valid_pixels[i] = CountValid(valid);
        }
        info.width = image.width();
        info.height = image.height();
        info.channels = image.channels();
        info.type = image.type();
        data.images[i] = std::move(image);
      } else {
        info = ReadImageInfo(frame.path);
        if (info.width <= 0 || info.height <= 0) ThrowInvalid(frame.path + ": image is empty");
        if (info.channels < 1 || info.channels > 4) {
          ThrowInvalid(frame.path + ": image has " + std::to_string(info.channels) +
                       " channels; aos reads 1 to 4");
        }
        if (options.grey) info.channels = 1;
      }
    } catch (const std::invalid_argument& error) {
      ThrowInvalid(Where(frame.label, error.what()));
    }
  });
  return data;
}

// Marks the light field masked and notes what the masks leave (an all-zero mask is no error:
// its frame contributes nothing).
void NoteMasks(const std::vector<Frame>& frames, const FrameData& data, const FrameMasks& masks,
               const LoadOptions& options, LightField& light_field,
               std::vector<std::string>& notes) {
  if (!masks.enabled) return;
  light_field.masked = true;
  int64_t least = -1, most = 0;
  size_t empty = 0, first_empty = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const int64_t valid = data.valid_pixels[i];
    least = least < 0 ? valid : std::min(least, valid);
    most = std::max(most, valid);
    if (valid == 0 && empty++ == 0) first_empty = i;
  }
  const double pixels = static_cast<double>(data.infos[0].width) * data.infos[0].height;
  const auto percent = [&](int64_t valid) { return FormatNumber(std::round(1000.0 * valid / pixels) / 10.0) + "%"; };
  if (masks.paths.empty()) {
    notes.push_back("mask " + options.mask + ": " + percent(most) + " of each frame is valid" +
                    (most == 0 ? " (all zero: every view contributes nothing, every pixel of a "
                                 "render is uncovered)"
                               : ""));
    return;
  }
  notes.push_back("mask_dir " + options.mask_dir + ": " + std::to_string(frames.size()) +
                  " masks, " + percent(least) + " to " + percent(most) + " of a frame valid");
  if (empty > 0) {
    notes.push_back(Where(frames[first_empty].label,
                          "mask " + masks.paths[first_empty] + " is all zero: the view "
                          "contributes nothing" +
                          (empty > 1 ? " (" + std::to_string(empty) + " views have such masks)"
                                     : std::string())));
  }
}


// Checks frame sizes against the cameras and channel counts against frame 0 (the checks
// CheckView/CheckLightField make, done from the file headers so they also apply when the
// images are not decoded).
void CheckFrameInfos(const std::vector<Frame>& frames, const std::vector<ImageFileInfo>& infos,
                     const std::vector<View>& views) {
  for (size_t i = 0; i < frames.size(); ++i) {
    const ImageFileInfo& info = infos[i];
    const LensCamera& camera = views[i].camera;
    if (info.width != camera.width || info.height != camera.height) {
      ThrowInvalid(Where(frames[i].label, "image " + frames[i].path + " is " +
                                              SizeText(info.width, info.height) +
                                              " but the camera says " +
                                              SizeText(camera.width, camera.height)));
    }
    if (info.channels != infos[0].channels) {
      ThrowInvalid(Where(frames[i].label, "image has " + std::to_string(info.channels) +
                                              " channels but view 0 has " +
                                              std::to_string(infos[0].channels)));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The aos format.

// The pose record ("pose_source"): where estimated poses came from (sfm/).
PoseSource ReadPoseSourceJson(const json& value, const JsonPath& at) {
  RequireKnownKeys(value, {"method", "mean_reprojection_error_px", "median_depth", "pose_error",
                           "georeferenced", "georeference_rms_m", "world_frame", "unregistered"},
                   at);
  PoseSource p;
  const auto number = [&](const char* key, double* out) {
    if (auto field = value.find(key); field != value.end()) {
      *out = ReadJsonNumber(*field, at / key);
      if (*out < 0) (at / key).Fail("expected a finite number >= 0, got " + DescribeJson(*field));
    }
  };
  const auto text = [&](const char* key, std::string* out) {
    if (auto field = value.find(key); field != value.end()) {
      if (!field->is_string()) (at / key).Fail("expected a string, got " + DescribeJson(*field));
      *out = field->get<std::string>();
    }
  };
  text("method", &p.method);
  text("world_frame", &p.world_frame);
  number("mean_reprojection_error_px", &p.mean_reprojection_error_px);
  number("median_depth", &p.median_depth);
  number("pose_error", &p.pose_error);
  number("georeference_rms_m", &p.georeference_rms_m);
  if (auto field = value.find("georeferenced"); field != value.end()) {
    if (!field->is_boolean()) {
      (at / "georeferenced").Fail("expected true or false, got " + DescribeJson(*field));
    }
    p.georeferenced = field->get<bool>();
  }
  if (auto field = value.find("unregistered"); field != value.end()) {
    if (!field->is_array()) {
      (at / "unregistered").Fail("expected an array of frame names, got " + DescribeJson(*field));
    }
    for (size_t i = 0; i < field->size(); ++i) {
      const json& name = (*field)[i];
      if (!name.is_string()) (at / "unregistered" / i).Fail("expected a frame name, got " + DescribeJson(name));
      p.unregistered.push_back(name.get<std::string>());
    }
  }
  return p;
}

nlohmann::ordered_json PoseSourceToJson(const PoseSource& p) {
  nlohmann::ordered_json value = {{"method", p.method},
                                  {"mean_reprojection_error_px", p.mean_reprojection_error_px},
                                  {"median_depth", p.median_depth},
                                  {"pose_error", p.pose_error},
                                  {"georeferenced", p.georeferenced},
                                  {"georeference_rms_m", p.georeference_rms_m}};
  // Only a frame without an EPSG code is described here; "crs" says the others.
  if (!p.world_frame.empty()) value["world_frame"] = p.world_frame;
  value["unregistered"] = p.unregistered;
  return value;
}

// The EPSG code an older file's pose_source.world_frame label names, or "": aos wrote
// "UTM 33N (WGS84)" (WGS84 / UTM, whatever the positions' own datum, since they were projected
// to EPSG:326zz/327zz) or a projected CRS's name ("ETRS89 / UTM zone 33N"), which PROJ
// identifies.
std::string CrsFromWorldFrameLabel(const std::string& label) {
  int zone = 0;
  char hemisphere = 0;
  if (std::sscanf(label.c_str(), "UTM %d%c", &zone, &hemisphere) == 2 && zone >= 1 &&
      zone <= 60 && (hemisphere == 'N' || hemisphere == 'S')) {
    return UtmEpsg(zone, hemisphere == 'N');
  }
  try {
    const std::string epsg = EpsgOfCrs(label, "world_frame");
    if (epsg.empty()) return "";
    CheckLightFieldCrs(epsg, "world_frame");
    return epsg;
  } catch (const std::invalid_argument&) {
    return "";  // a free description ("the frame of gps.csv"): kept as it is
  }
}

LoadResult LoadAos(const std::string& path, const json& root, const LoadOptions& options,
                   ProgressSink* progress) {
  const json& version = Field(root, "version", path);
  if (!version.is_number_integer() || version.get<int64_t>() != kAosFormatVersion) {
    ThrowInvalid(path + ": version: expected " + std::to_string(kAosFormatVersion) + ", got " +
                 Describe(version) + " (written by a newer aos?)");
  }
  const JsonPath top(path);
  RequireKnownKeys(root,
                   {"format", "version", "origin", "crs", "pose_source", "grey", "radiometry",
                    "cameras", "views"},
                   top);
  LoadResult result;
  result.format = "aos";
  LightField& light_field = result.light_field;
  if (auto it = root.find("origin"); it != root.end()) {
    light_field.origin = ReadVec3Json(*it, top / "origin");
  }
  if (auto it = root.find("crs"); it != root.end()) {
    if (!it->is_string()) {
      ThrowInvalid(path + ": crs: expected a string \"EPSG:<code>\", got " + Describe(*it));
    }
    light_field.crs = it->get<std::string>();
    CheckLightFieldCrs(light_field.crs, path + ": crs");
  }
  if (auto it = root.find("pose_source"); it != root.end()) {
    light_field.pose_source = ReadPoseSourceJson(*it, top / "pose_source");
    // Files written before "crs" named UTM frames in pose_source.world_frame only.
    PoseSource& source = *light_field.pose_source;
    if (light_field.crs.empty() && !source.world_frame.empty()) {
      light_field.crs = CrsFromWorldFrameLabel(source.world_frame);
      if (!light_field.crs.empty()) {
        result.notes.push_back(path + ": pose_source.world_frame \"" + source.world_frame +
                               "\" read as crs " + light_field.crs);
        source.world_frame.clear();
      }
    }
  }

  if (auto it = root.find("grey"); it != root.end()) {
    if (!it->is_boolean()) ThrowInvalid(path + ": grey: expected true or false, got " + Describe(*it));
    light_field.grey = it->get<bool>();
  }
  if (auto it = root.find("radiometry"); it != root.end()) {
    const JsonPath at = top / "radiometry";
    if (!it->is_object()) {
      ThrowInvalid(path + ": radiometry: expected an object {\"kelvin_per_unit\": ..., "
                   "\"kelvin_offset\": ...}, got " + Describe(*it));
    }
    RequireKnownKeys(*it, {"kelvin_per_unit", "kelvin_offset"}, at);
    Radiometry radiometry;
    for (const auto& [key, field] : {std::pair<const char*, double*>{"kelvin_per_unit",
                                                                     &radiometry.kelvin_per_unit},
                                     {"kelvin_offset", &radiometry.kelvin_offset}}) {
      const json& value = Field(*it, key, path + ": radiometry");
      if (!value.is_number()) {
        ThrowInvalid(path + ": radiometry: " + key + ": expected a number, got " + Describe(value));
      }
      *field = value.get<double>();
    }
    radiometry.Check(path + ": radiometry");
    light_field.radiometry = radiometry;
  }

  const json& cameras_json = Field(root, "cameras", path);
  if (!cameras_json.is_object()) {
    ThrowInvalid(path + ": cameras: expected an object keyed by camera id, got " +
                 Describe(cameras_json));
  }
  std::map<std::string, LensCamera> cameras;
  for (const auto& [id, value] : cameras_json.items()) {
    cameras[id] = ReadCameraJson(value, top / "cameras" / id);
  }

  const json& views_json = Field(root, "views", path);
  if (!views_json.is_array()) {
    ThrowInvalid(path + ": views: expected an array, got " + Describe(views_json));
  }
  if (views_json.empty()) ThrowInvalid(path + ": views: the light field has no views");
  const std::string folder = ParentFolder(path);
  FolderIndex folder_index;
  int case_substitutions = 0;
  std::string case_example;
  std::vector<Frame> frames;
  for (size_t i = 0; i < views_json.size(); ++i) {
    const json& entry = views_json[i];
    std::string label = path + ": view " + std::to_string(i);
    if (!entry.is_object()) ThrowInvalid(label + ": expected an object, got " + Describe(entry));
    RequireKnownKeys(entry, {"image", "name", "camera", "cam_from_world"}, top / "views" / i);
    const std::string image = StringFrom(Field(entry, "image", label), label + ": image");
    label += " (" + image + ")";
    View view;
    view.name = image;
    if (auto name = entry.find("name"); name != entry.end()) {
      view.name = StringFrom(*name, label + ": name");
      if (view.name.empty()) ThrowInvalid(label + ": name: is empty");
    }
    view.image_path = ResolvePath(folder, image);
    // A frame named a.jpg on disk as a.JPG (cameras write upper case, tools lower).
    const std::string found = FindFrameFile(view.image_path, folder_index, label, "image");
    if (!found.empty() && found != view.image_path) {
      if (case_substitutions++ == 0) {
        case_example = image + " -> " + fs::path(found).filename().string();
      }
      view.image_path = found;
    }
    const std::string camera_id = StringFrom(Field(entry, "camera", label), label + ": camera");
    auto camera = cameras.find(camera_id);
    if (camera == cameras.end()) {
      std::string known;
      for (const auto& [id, unused] : cameras) known += (known.empty() ? "" : ", ") + Quoted(id);
      ThrowInvalid(label + ": camera: unknown camera id " + Quoted(camera_id) + " (known: " +
                   (known.empty() ? std::string("none") : known) + ")");
    }
    view.camera = camera->second;
    // Errors name the JSON pointer and, for people, the view and its image.
    const JsonPath view_at = (top / "views" / i).Noted("view " + std::to_string(i) + ": " + image);
    view.cam_from_world = ReadPoseJson(Field(entry, "cam_from_world", label),
                                       view_at / "cam_from_world");
    frames.push_back(Frame{label, view.image_path});
    light_field.views.push_back(std::move(view));
  }

  if (case_substitutions > 0) {
    result.notes.push_back(path + ": " + std::to_string(case_substitutions) + " frame" +
                           (case_substitutions == 1 ? " was" : "s were") +
                           " found under a name that differs only in case (e.g. " + case_example +
                           ")");
  }
  // Poses and cameras only: the frames are not opened at all (they may be elsewhere or absent).
  if (!options.load_images) return result;
  LoadOptions decode = options;
  decode.grey = options.grey || light_field.grey;  // the file's "grey" holds for every load
  const FrameMasks masks = ResolveMasks(frames, decode);
  FrameData data = ReadFrames(frames, decode, progress, masks);
  CheckFrameInfos(frames, data.infos, light_field.views);
  for (size_t i = 0; i < frames.size(); ++i) light_field.views[i].image = std::move(data.images[i]);
  NoteMasks(frames, data, masks, decode, light_field, result.notes);
  CheckLightField(light_field, path);
  return result;
}

// ---------------------------------------------------------------------------------------------
// The JKU-ICG/AOS poses.json.

bool LooksLikeJku(const json& root) {
  auto images = root.find("images");
  if (images == root.end() || !images->is_array()) return false;
  for (const json& entry : *images) {
    if (entry.is_object() && entry.contains("M3x4")) return true;
  }
  return false;
}

Rigid3d ReadJkuPose(const json& value, const std::string& where) {
  const std::string shape_error = "expected 3 rows of 4 numbers, got ";
  if (!value.is_array() || value.size() != 3) ThrowInvalid(Where(where, shape_error + Describe(value)));
  std::array<double, 12> rows{};
  for (int r = 0; r < 3; ++r) {
    const json& row = value[r];
    if (!row.is_array() || row.size() != 4) {
      ThrowInvalid(Where(where, shape_error + Describe(value)));
    }
    for (int c = 0; c < 4; ++c) {
      rows[4 * r + c] = NumberFrom(
          row[c], where + "[" + std::to_string(r) + "][" + std::to_string(c) + "]", true);
    }
  }
  const Rigid3d pose = Rigid3d::FromMatrix3x4(rows);
  CheckPose(pose, where);
  return pose;
}

// The folder holding the frames of JKU poses file `path`.
std::string JkuFramesFolder(const std::string& path, const LoadOptions& options) {
  std::error_code error;
  if (!options.images_dir.empty()) {
    if (!fs::is_directory(options.images_dir, error)) {
      ThrowInvalid(path + ": images_dir: folder " + Quoted(options.images_dir) +
                   " does not exist");
    }
    return options.images_dir;
  }
  const std::string poses_folder = ParentFolder(path);
  const std::string beside = (fs::path(poses_folder) / ".." / "images").string();
  if (fs::is_directory(beside, error)) return beside;
  return poses_folder;
}

LoadResult LoadJku(const std::string& path, const json& root, const LoadOptions& options,
                   ProgressSink* progress) {
  if (options.fov_deg == 0.0) {
    ThrowInvalid(path + ": fov_deg: a JKU poses file has no intrinsics; give the horizontal "
                        "field of view of the frames in degrees (LoadOptions::fov_deg)");
  }
  LoadResult result;
  result.format = "jku";
  LightField& light_field = result.light_field;
  const json& images = root["images"];
  const std::string folder = JkuFramesFolder(path, options);
  // For messages only: "poses/../images" reads better as "images" (access uses `folder`).
  const std::string folder_text = fs::path(folder).lexically_normal().string();

  // Substituted names, grouped by (named extension, found extension): count and first example.
  struct Substitution {
    int count = 0;
    std::string example;
  };
  std::map<std::pair<std::string, std::string>, Substitution> substitutions;
  std::vector<std::pair<std::string, std::string>> substitution_order;
  FolderIndex folder_index;
  int first_found = -1;     // the first view whose frame exists (sizes the camera)
  int frames_missing = 0;   // without load_images only

  std::vector<Frame> frames;
  for (size_t i = 0; i < images.size(); ++i) {
    const json& entry = images[i];
    std::string label = path + ": image " + std::to_string(i);
    if (!entry.is_object()) ThrowInvalid(label + ": expected an object, got " + Describe(entry));
    const std::string imagefile =
        StringFrom(Field(entry, "imagefile", label), label + ": imagefile");
    label += " (" + imagefile + ")";
    View view;
    view.name = imagefile;
    view.cam_from_world = ReadJkuPose(Field(entry, "M3x4", label), label + ": M3x4");

    // The frame: its own name (exactly, then ignoring case), then the same stem with another
    // image extension (likewise).
    std::string frame_path = ResolvePath(folder, imagefile);
    std::string found = FindFrameFile(frame_path, folder_index, label, "imagefile");
    std::string tried;
    if (found.empty()) {
      const fs::path named(frame_path);
      const std::string named_extension = Lower(named.extension().string());
      for (const char* extension : kFrameExtensions) {
        if (named_extension == extension) continue;
        tried += (tried.empty() ? "" : ", ") + std::string(extension);
        found = FindFrameFile(fs::path(named).replace_extension(extension).string(), folder_index,
                              label, "imagefile");
        if (!found.empty()) break;
      }
    }
    if (found.empty()) {
      if (options.load_images) {
        ThrowInvalid(label + ": imagefile: frame not found in " + Quoted(folder_text) +
                     " (also tried the name ignoring case and the extensions " + tried + ")");
      }
      ++frames_missing;  // poses only: the view keeps the name it was given
    } else if (found != frame_path) {
      const fs::path named(frame_path);
      const auto key = std::make_pair(named.extension().string(),
                                      fs::path(found).extension().string());
      Substitution& substitution = substitutions[key];
      if (substitution.count++ == 0) {
        substitution.example = imagefile + " -> " + fs::path(found).filename().string();
        substitution_order.push_back(key);
      }
      frame_path = found;
    }
    if (first_found < 0 && !found.empty()) first_found = static_cast<int>(i);
    view.image_path = frame_path;
    frames.push_back(Frame{label, frame_path});
    light_field.views.push_back(std::move(view));
  }
  for (const auto& key : substitution_order) {
    const Substitution& substitution = substitutions[key];
    const std::string named = key.first.empty() ? std::string("without an extension")
                                                : "*" + key.first;
    result.notes.push_back(path + ": " + std::to_string(substitution.count) + " frame" +
                           (substitution.count == 1 ? "" : "s") + " named " + named +
                           (substitution.count == 1 ? " was" : " were") + " found as *" +
                           key.second + " in " + folder_text + " (e.g. " + substitution.example +
                           ")");
  }

  if (first_found < 0) {
    // Without load_images (else the first missing frame was an error already).
    ThrowInvalid(path + ": imagefile: none of the " + std::to_string(frames.size()) +
                 " frames was found in " + Quoted(folder_text) +
                 "; a JKU poses file has no image size, so even without loading images one "
                 "frame is read to size the camera (give images_dir)");
  }
  if (frames_missing > 0) {
    result.notes.push_back(path + ": " + std::to_string(frames_missing) + " of " +
                           std::to_string(frames.size()) + " frames not found in " +
                           folder_text + "; loaded without images, their views keep the names "
                           "given");
  }
  FrameData data;
  FrameMasks masks;
  if (options.load_images) {
    masks = ResolveMasks(frames, options);
    data = ReadFrames(frames, options, progress, masks);
  } else {
    // Poses only: the first frame that exists sizes the one camera; no other frame is opened.
    ReadFrames({frames[first_found]}, options, nullptr).infos.swap(data.infos);
    data.infos.resize(frames.size(), data.infos[0]);
  }
  // One camera for all frames, sized by the first frame.
  PinholeCamera camera;
  try {
    camera = PinholeCamera::FromFov(data.infos[0].width, data.infos[0].height, options.fov_deg);
  } catch (const std::invalid_argument& error) {
    ThrowInvalid(Where(frames[first_found].label, error.what()));
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    const ImageFileInfo& info = data.infos[i];
    if (info.width != camera.width || info.height != camera.height) {
      ThrowInvalid(frames[i].label + ": image " + frames[i].path + " is " +
                   SizeText(info.width, info.height) + " but the first frame is " +
                   SizeText(camera.width, camera.height) +
                   " (all frames of a poses file share one camera)");
    }
    light_field.views[i].camera = LensCamera::FromPinhole(camera);
  }
  CheckFrameInfos(frames, data.infos, light_field.views);
  if (options.load_images) {
    for (size_t i = 0; i < frames.size(); ++i) light_field.views[i].image = std::move(data.images[i]);
    NoteMasks(frames, data, masks, options, light_field, result.notes);
    CheckLightField(light_field, path);
  }
  return result;
}

// ---------------------------------------------------------------------------------------------
// Writing.

// How `image_path` is written into a JSON file in `json_folder`: relative when the two share a
// folder below the root and the relative path names the same file, else absolute (a path that
// climbs to "/" and back down is no more portable than the absolute one).
std::string ReferencePath(const std::string& image_path, const std::string& json_folder) {
  std::error_code error;
  const fs::path image = fs::weakly_canonical(fs::absolute(image_path), error);
  if (error) return fs::absolute(image_path).string();
  const fs::path folder = fs::weakly_canonical(fs::absolute(json_folder), error);
  if (error) return image.string();
  const fs::path relative = image.lexically_relative(folder);
  if (relative.empty()) return image.string();
  const auto ups = std::count(relative.begin(), relative.end(), fs::path(".."));
  const fs::path folder_below_root = folder.relative_path();
  const auto folder_depth = std::distance(folder_below_root.begin(), folder_below_root.end());
  if (ups >= folder_depth) return image.string();
  std::error_code equivalent_error;
  if (!fs::equivalent(fs::path(json_folder) / relative, image, equivalent_error)) {
    return image.string();
  }
  return relative.generic_string();
}

std::string ViewLabel(const std::string& where, size_t index, const View& view) {
  std::string label = where + ": view " + std::to_string(index);
  if (!view.name.empty()) label += " (" + view.name + ")";
  return label;
}

}  // namespace

void LoadOptions::Check() const {
  CheckFieldRanges(*this);  // the table's ranges (formats.h)
  if (!mask.empty() && !mask_dir.empty()) {
    ThrowInvalid("mask/mask_dir: give one mask for all frames or a folder of masks, not both");
  }
}

double ParseNumberText(const std::string& text, const std::string& where) {
  // Grammar: [+-] (digits [. digits*] | . digits) [(e|E) [+-] digits], the whole text.
  const std::string not_a_number = Where(where, Quoted(text) + " is not a number");
  const std::string lowered = Lower(text);
  const std::string unsigned_text =
      (!lowered.empty() && (lowered[0] == '+' || lowered[0] == '-')) ? lowered.substr(1) : lowered;
  if (unsigned_text == "nan" || unsigned_text == "inf" || unsigned_text == "infinity") {
    ThrowInvalid(not_a_number + " (not finite)");
  }
  size_t i = 0;
  const size_t n = text.size();
  auto digits = [&] {
    const size_t start = i;
    while (i < n && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
    return i - start;
  };
  if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
  size_t mantissa_digits = digits();
  if (i < n && text[i] == '.') {
    ++i;
    mantissa_digits += digits();
  }
  bool valid = mantissa_digits > 0;
  if (valid && i < n && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
    valid = digits() > 0;
  }
  if (!valid || i != n) ThrowInvalid(not_a_number);
  // from_chars does not take a leading '+' and ignores the locale (unlike strtod).
  const char* begin = text.data() + (text[0] == '+' ? 1 : 0);
  double value = 0.0;
  const auto [end, error] = std::from_chars(begin, text.data() + n, value);
  if (error == std::errc::result_out_of_range) ThrowInvalid(not_a_number + " (out of range)");
  if (error != std::errc() || end != text.data() + n) ThrowInvalid(not_a_number);
  if (!std::isfinite(value)) ThrowInvalid(not_a_number + " (not finite)");
  return value;
}

namespace {
LoadResult LoadFromJson(const std::string& path, const json& root, const LoadOptions& options,
                        ProgressSink* progress);
}  // namespace

namespace {

void CheckViewIndices(const LightField& light_field, const std::vector<int>& indices) {
  for (int index : indices) {
    if (index < 0 || static_cast<size_t>(index) >= light_field.views.size()) {
      ThrowInvalid("indices: " + std::to_string(index) + " is not a view (the light field has " +
                   std::to_string(light_field.views.size()) + ")");
    }
  }
}

}  // namespace

void LoadViewImages(LightField& light_field, const std::vector<int>& indices,
                    const LoadOptions& options) {
  options.Check();
  CheckViewIndices(light_field, indices);
  if (indices.empty()) return;
  std::vector<Frame> frames;
  std::vector<View> views;  // the cameras CheckFrameInfos compares with
  for (int index : indices) {
    const View& view = light_field.views[static_cast<size_t>(index)];
    const std::string label = "view " + std::to_string(index) + " (" + view.image_path + ")";
    if (view.image_path.empty()) ThrowInvalid(label + ": image_path: the view has no frame file");
    frames.push_back(Frame{label, view.image_path});
    views.push_back(view);
  }
  LoadOptions decode = options;
  decode.load_images = true;
  decode.grey = options.grey || light_field.grey;
  const FrameMasks masks = ResolveMasks(frames, decode);
  FrameData data = ReadFrames(frames, decode, nullptr, masks);
  CheckFrameInfos(frames, data.infos, views);
  for (size_t i = 0; i < indices.size(); ++i) {
    light_field.views[static_cast<size_t>(indices[i])].image = std::move(data.images[i]);
  }
  if (masks.enabled) light_field.masked = true;
}

void DropViewImages(LightField& light_field, const std::vector<int>& indices) {
  CheckViewIndices(light_field, indices);
  for (int index : indices) light_field.views[static_cast<size_t>(index)].image = Image();
}

LoadResult LoadLightField(const std::string& path, const LoadOptions& options,
                          ProgressSink* progress) {
  options.Check();
  const json root = ParseJsonFile(path);
  return WithJsonErrorsNamed(path, [&] { return LoadFromJson(path, root, options, progress); });
}

namespace {

LoadResult LoadFromJson(const std::string& path, const json& root, const LoadOptions& options,
                        ProgressSink* progress) {
  const std::string expected =
      "expected an aos light field ({\"format\": \"aos-lightfield\", ...}) or a JKU poses file "
      "({\"images\": [{\"imagefile\": ..., \"M3x4\": ...}]})";
  if (!root.is_object()) ThrowInvalid(path + ": unknown light-field format; " + expected);
  if (auto format = root.find("format"); format != root.end()) {
    if (format->is_string() && format->get<std::string>() == kAosFormatName) {
      return LoadAos(path, root, options, progress);
    }
    ThrowInvalid(path + ": format: unknown light-field format " + Describe(*format) + "; " +
                 expected);
  }
  if (LooksLikeJku(root)) return LoadJku(path, root, options, progress);
  ThrowInvalid(path + ": unknown light-field format; " + expected);
}

}  // namespace

void WriteLightField(const std::string& path, const LightField& light_field,
                     const WriteLightFieldOptions& options) {
  // Options and light field first: nothing is written unless everything can be.
  if (light_field.masked) {
    // Its frames hold premultiplied values and a weight channel (lightfield/mask.h); the aos
    // JSON has no place for that, and the frames its views name are the unmasked files.
    ThrowInvalid(path + ": the light field is masked (loaded with a mask: its frames carry a "
                 "weight channel): writing it would store premultiplied frames, or drop the "
                 "mask, silently. Write the light field loaded without the mask, and give the "
                 "mask again when loading it (--mask/--mask-dir)");
  }
  const std::string& extension = options.image_extension;
  if (extension.size() < 2 || extension[0] != '.' ||
      extension.find_first_of("/\\") != std::string::npos) {
    ThrowInvalid("image_extension: expected a file extension such as \".png\" (got " +
                 Quoted(extension) + ")");
  }
  if (fs::path(options.images_subdir).is_absolute()) {
    ThrowInvalid("images_subdir: must be relative to the light-field file's folder (got " +
                 Quoted(options.images_subdir) + ")");
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(light_field.origin[i])) ThrowInvalid(path + ": origin is not finite");
  }
  CheckLightFieldCrs(light_field.crs, path + ": crs");
  if (light_field.views.empty()) ThrowInvalid(path + ": the light field has no views");
  std::vector<std::string> inputs;
  const View* first_with_image = nullptr;
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    const std::string label = ViewLabel(path, i, view);
    view.camera.Pinhole().Check(label);
    if (auto problem = DescribeInvalidRigid(view.cam_from_world)) {
      ThrowInvalid(label + ": cam_from_world: " + *problem);
    }
    if (!view.image_path.empty()) {
      if (!IsFile(view.image_path)) {
        ThrowInvalid(label + ": image_path: " + Quoted(view.image_path) + " is not a file");
      }
      inputs.push_back(view.image_path);
      continue;
    }
    if (view.image.empty()) {
      ThrowInvalid(label + ": image: no pixels and no image_path; nothing to write or reference");
    }
    if (view.image.width() != view.camera.width || view.image.height() != view.camera.height) {
      ThrowInvalid(label + ": image is " + SizeText(view.image.width(), view.image.height()) +
                   " but the camera says " + SizeText(view.camera.width, view.camera.height));
    }
    if (view.image.type() == PixelType::kU32) {
      ThrowInvalid(label + ": image: uint32 views are not supported (use 8/16-bit or float)");
    }
    if (first_with_image == nullptr) first_with_image = &view;
    if (view.image.channels() != first_with_image->image.channels()) {
      ThrowInvalid(label + ": image has " + std::to_string(view.image.channels()) +
                   " channels but " + first_with_image->name + " has " +
                   std::to_string(first_with_image->image.channels()));
    }
  }
  CheckOutputPath(path, inputs, "light-field file");

  const std::string folder = ParentFolder(path);
  const fs::path images_folder = fs::path(folder) / options.images_subdir;
  std::vector<std::string> written(light_field.views.size());  // path to write, or empty
  const bool any_written = std::any_of(light_field.views.begin(), light_field.views.end(),
                                       [](const View& view) { return view.image_path.empty(); });
  if (any_written) {
    std::error_code error;
    fs::create_directories(images_folder, error);
    if (error || !fs::is_directory(images_folder)) {
      ThrowInvalid(images_folder.string() + ": images_subdir: cannot create the folder" +
                   (error ? " (" + error.message() + ")" : std::string()));
    }
  }
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    if (!light_field.views[i].image_path.empty()) continue;
    char name[32];
    std::snprintf(name, sizeof(name), "%04zu", i);
    written[i] = (images_folder / (std::string(name) + extension)).string();
    CheckOutputPath(written[i], inputs, "view image");
  }

  ParallelFor(static_cast<int64_t>(light_field.views.size()), -1, nullptr,
              [&](int64_t i) {
                if (!written[i].empty()) WriteImage(written[i], light_field.views[i].image);
              });

  // The JSON, in the documented field order, cameras shared where identical.
  nlohmann::ordered_json root;
  root["format"] = kAosFormatName;
  root["version"] = kAosFormatVersion;
  root["origin"] = Vec3ToJson(light_field.origin);
  if (!light_field.crs.empty()) root["crs"] = light_field.crs;
  if (light_field.pose_source) root["pose_source"] = PoseSourceToJson(*light_field.pose_source);
  if (light_field.grey) root["grey"] = true;
  if (light_field.radiometry) {
    root["radiometry"] = {{"kelvin_per_unit", light_field.radiometry->kelvin_per_unit},
                          {"kelvin_offset", light_field.radiometry->kelvin_offset}};
  }
  std::vector<const View*> cameras;  // the first view of each distinct camera
  nlohmann::ordered_json cameras_json = nlohmann::ordered_json::object();
  nlohmann::ordered_json views_json = nlohmann::ordered_json::array();
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    size_t camera_index = 0;
    while (camera_index < cameras.size() &&
           !cameras[camera_index]->camera.SameParameters(view.camera)) {
      ++camera_index;
    }
    const std::string camera_id = "cam" + std::to_string(camera_index);
    if (camera_index == cameras.size()) {
      cameras.push_back(&view);
      cameras_json[camera_id] = CameraToJson(view.camera);
    }
    const std::string image =
        written[i].empty() ? ReferencePath(view.image_path, folder)
                           : (fs::path(options.images_subdir) / fs::path(written[i]).filename())
                                 .generic_string();
    nlohmann::ordered_json view_json;
    view_json["image"] = image;
    // The name the view was imported with (a frame's name, "15.png"), where the image path
    // written differs from it ("../../x/15.png", "views/0003.png").
    if (!view.name.empty() && view.name != image) view_json["name"] = view.name;
    view_json["camera"] = camera_id;
    view_json["cam_from_world"] = PoseToJson(view.cam_from_world);
    views_json.push_back(view_json);
  }
  root["cameras"] = cameras_json;
  root["views"] = views_json;
  WriteTextFileAtomic(path, root.dump(2) + "\n");
}

}  // namespace aos
