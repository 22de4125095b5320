#include "aos/lightfield/lightfield.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <utility>

#include "aos/util/error.h"

namespace aos {

LightField EmptyLike(const LightField& light_field) {
  LightField empty;
  empty.origin = light_field.origin;
  empty.crs = light_field.crs;
  empty.pose_source = light_field.pose_source;
  empty.masked = light_field.masked;
  empty.grey = light_field.grey;
  empty.radiometry = light_field.radiometry;
  return empty;
}

size_t LightField::ImageBytes() const {
  size_t bytes = 0;
  for (const View& view : views) bytes += view.image.PixelBytes();
  return bytes;
}

void CheckView(const View& view, const std::string& where) {
  view.camera.Pinhole().Check(where);
  if (!view.camera.IsPinhole() && !(view.camera.theta_max > 0.0)) {
    ThrowInvalid(Where(where, "camera: the lens's valid field is not set (LensCamera::Finalize)"));
  }
  if (auto problem = DescribeInvalidRigid(view.cam_from_world)) {
    ThrowInvalid(Where(where, "cam_from_world: " + *problem));
  }
  if (view.image.empty()) ThrowInvalid(Where(where, "image: no pixels (image not loaded)"));
  if (view.image.width() != view.camera.width || view.image.height() != view.camera.height) {
    ThrowInvalid(Where(where, "image is " + std::to_string(view.image.width()) + "x" +
                                  std::to_string(view.image.height()) + " but the camera says " +
                                  std::to_string(view.camera.width) + "x" +
                                  std::to_string(view.camera.height)));
  }
  if (view.image.border() < 1) ThrowInvalid(Where(where, "image: needs a border of 1 pixel"));
  // Sample positions are single-precision floats in the inner loops: keep them exact to well
  // below a pixel.
  constexpr int kMaxSide = 1 << 22;
  if (view.image.width() > kMaxSide || view.image.height() > kMaxSide) {
    ThrowInvalid(Where(where, "image: wider or taller than 4194304 pixels"));
  }
  if (view.image.type() == PixelType::kU32) {
    ThrowInvalid(Where(where, "image: uint32 views are not supported (use 8/16-bit or float)"));
  }
}

static std::string ViewLabel(const std::string& where, size_t index, const View& view) {
  std::string label = where + ": view " + std::to_string(index);
  if (!view.name.empty()) label += " (" + view.name + ")";
  return label;
}

void CheckLightField(const LightField& light_field, const std::string& where) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(light_field.origin[i])) ThrowInvalid(Where(where, "origin is not finite"));
  }
  if (light_field.radiometry) light_field.radiometry->Check(Where(where, "radiometry"));
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    CheckView(view, ViewLabel(where, i, view));
    if (view.image.channels() != light_field.views[0].image.channels()) {
      ThrowInvalid(ViewLabel(where, i, view) + ": image has " +
                   std::to_string(view.image.channels()) + " channels but view 0 has " +
                   std::to_string(light_field.views[0].image.channels()));
    }
    if (light_field.masked && view.image.channels() < 2) {
      ThrowInvalid(ViewLabel(where, i, view) + ": masked: the light field is masked but the "
                   "image has no weight channel (1 channel)");
    }
    const int value_channels = light_field.masked ? 2 : 1;
    if (light_field.radiometry && !view.image.empty() && view.image.channels() != value_channels) {
      ThrowInvalid(ViewLabel(where, i, view) + ": radiometry: temperature frames have one "
                   "channel" + (light_field.masked ? " and a weight" : "") + ", this image has " +
                   std::to_string(view.image.channels()));
    }
  }
}

namespace {

std::string LowerText(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// Edit distance (insertions, deletions, substitutions), for suggesting close names.
size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::string NameList(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += (text.empty() ? "\"" : ", \"") + name + "\"";
  return text;
}

}  // namespace

std::string ViewNameAndFile(const View& view, int index) {
  namespace fs = std::filesystem;
  // The frame file with its folder ("views/0004.png"): two folders may hold one file name.
  const fs::path image(view.image_path);
  const std::string file = image.has_parent_path() && image.parent_path().has_filename()
                               ? (image.parent_path().filename() / image.filename()).generic_string()
                               : image.filename().generic_string();
  std::string text = view.name + " (view " + std::to_string(index);
  if (!file.empty() && file != fs::path(view.name).generic_string()) text += ", file " + file;
  return text + ")";
}

int FindViewByName(const LightField& light_field, const std::string& name,
                   const std::string& where) {
  namespace fs = std::filesystem;
  if (name.empty()) ThrowInvalid(Where(where, "empty view name"));
  // The spellings a view answers to: its name, its file name, and that file name's stem; its
  // frame file's name and stem; and, for a name with folders, the frame file's trailing path.
  const std::string wanted_path = fs::path(name).lexically_normal().generic_string();
  const bool has_folders = name.find('/') != std::string::npos;
  const auto spellings = [&](const View& view) {
    const fs::path path(view.name), file(view.image_path);
    std::vector<std::string> out{view.name, path.filename().string(), path.stem().string()};
    if (!view.image_path.empty()) {
      out.push_back(file.filename().string());
      out.push_back(file.stem().string());
      const std::string full = file.lexically_normal().generic_string();
      if (has_folders && full.size() > wanted_path.size() &&
          full[full.size() - wanted_path.size() - 1] == '/') {
        out.push_back(full.substr(full.size() - wanted_path.size()));
      }
    }
    return out;
  };
  const auto listed = [&](size_t index) {
    return ViewNameAndFile(light_field.views[index], static_cast<int>(index));
  };
  for (const bool ignore_case : {false, true}) {
    const std::string wanted = ignore_case ? LowerText(has_folders ? wanted_path : name)
                                           : (has_folders ? wanted_path : name);
    std::vector<int> matches;
    for (size_t i = 0; i < light_field.views.size(); ++i) {
      for (const std::string& spelling : spellings(light_field.views[i])) {
        if ((ignore_case ? LowerText(spelling) : spelling) == wanted) {
          matches.push_back(static_cast<int>(i));
          break;
        }
      }
    }
    if (matches.size() == 1) return matches[0];
    if (matches.size() > 1) {
      std::vector<std::string> names;
      for (int index : matches) names.push_back(listed(static_cast<size_t>(index)));
      ThrowInvalid(Where(where, "\"" + name + "\" is ambiguous: " +
                                    std::to_string(matches.size()) + " views match (" +
                                    NameList(names) + "); give the full name or the index"));
    }
  }
  // Unknown: suggest the closest stems (ignoring case), at most five.
  const std::string wanted = LowerText(fs::path(name).stem().string());
  std::vector<std::pair<size_t, size_t>> ranked;  // (distance, view)
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    size_t distance = std::numeric_limits<size_t>::max();
    for (const std::string& spelled :
         {light_field.views[i].name, light_field.views[i].image_path}) {
      if (spelled.empty()) continue;
      const std::string stem = LowerText(fs::path(spelled).stem().string());
      distance = std::min(distance, EditDistance(wanted, stem));
      if (!wanted.empty() && stem.find(wanted) != std::string::npos) {
        distance = std::min<size_t>(distance, 1);
      }
    }
    ranked.emplace_back(distance, i);
  }
  std::stable_sort(ranked.begin(), ranked.end());
  const size_t limit = std::max<size_t>(2, wanted.size() / 2);
  std::vector<std::string> close;
  for (const auto& [distance, index] : ranked) {
    if (close.size() == 5 || distance > limit) break;
    close.push_back(listed(index));
  }
  std::string hint;
  if (!close.empty()) {
    hint = "; close: " + NameList(close);
  } else if (!light_field.views.empty()) {
    hint = "; names run from \"" + light_field.views.front().name + "\" to \"" +
           light_field.views.back().name + "\"";
  }
  ThrowInvalid(Where(where, "no view named \"" + name + "\" among the " +
                                std::to_string(light_field.views.size()) + " views" + hint));
}

View MakeView(std::string name, const LensCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path) {
  View view;
  view.name = std::move(name);
  view.image_path = std::move(image_path);
  view.camera = camera;
  view.cam_from_world = cam_from_world;
  if (!image.empty() && image.border() < 1) {
    Image bordered(image.width(), image.height(), image.channels(), image.type(), 1);
    bordered.CopyFrom(image.RawAt(0, 0), image.row_stride());
    image = std::move(bordered);
  }
  view.image = std::move(image);
  const std::string where = view.name.empty() ? std::string("view") : "view " + view.name;
  view.camera.Pinhole().Check(where);
  if (!(view.camera.theta_max > 0.0)) view.camera.Finalize(Where(where, "camera"));
  CheckView(view, where);
  if (auto problem = DescribeNonFinite(view.image)) ThrowInvalid(Where(where, "image: " + *problem));
  return view;
}

View MakeView(std::string name, const PinholeCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path) {
  const std::string where = name.empty() ? std::string("view") : "view " + name;
  camera.Check(where);
  return MakeView(std::move(name), LensCamera::FromPinhole(camera), cam_from_world,
                  std::move(image), std::move(image_path));
}

}  // namespace aos
