#include "aos/util/file_util.h"

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include <unistd.h>

#include "aos/util/error.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

std::string MakeTempPath(const std::string& final_path) {
  static std::atomic<unsigned> counter{0};
  const fs::path path(final_path);
  const std::string stem = path.stem().string();
  const std::string extension = path.extension().string();
  const std::string name = "." + stem + ".tmp-" + std::to_string(::getpid()) + "-" +
                           std::to_string(counter.fetch_add(1)) + extension;
  return (path.parent_path() / name).string();
}

}  // namespace

PendingFile::PendingFile(std::string final_path)
    : final_path_(std::move(final_path)), temp_path_(MakeTempPath(final_path_)) {}

PendingFile::PendingFile(PendingFile&& other) noexcept
    : final_path_(std::move(other.final_path_)),
      temp_path_(std::move(other.temp_path_)),
      committed_(other.committed_) {
  other.committed_ = true;  // the moved-from object owns nothing
}

PendingFile::~PendingFile() {
  if (!committed_) {
    std::error_code ignored;
    fs::remove(temp_path_, ignored);
  }
}

void PendingFile::Commit() {
  std::error_code error;
  fs::rename(temp_path_, final_path_, error);
  if (error) {
    ThrowInvalid(final_path_ + ": cannot move the finished file into place (" + error.message() +
                 ")");
  }
  committed_ = true;
}

void CheckOutputPath(const std::string& output_path, const std::vector<std::string>& input_paths,
                     const std::string& what) {
  if (output_path.empty()) ThrowInvalid(what + ": the output path is empty");
  const fs::path path(output_path);
  const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code error;
  if (!fs::is_directory(folder, error)) {
    ThrowInvalid(output_path + ": " + what + ": folder '" + folder.string() + "' does not exist");
  }
  if (fs::is_directory(path, error)) {
    ThrowInvalid(output_path + ": " + what + ": is a folder, expected a file name");
  }
  if (!fs::exists(path, error)) return;
  for (const std::string& input : input_paths) {
    if (input.empty()) continue;
    std::error_code equivalent_error;
    if (fs::equivalent(path, fs::path(input), equivalent_error)) {
      ThrowInvalid(output_path + ": " + what +
                   ": refusing to overwrite an input file (it is the same file as " + input + ")");
    }
  }
}

void WriteTextFileAtomic(const std::string& path, const std::string& text) {
  PendingFile pending(path);
  {
    std::ofstream stream(pending.TempPath(), std::ios::binary);
    if (!stream) ThrowInvalid(path + ": cannot open for writing (" + std::strerror(errno) + ")");
    stream << text;
    stream.flush();
    if (!stream) ThrowInvalid(path + ": write failed");
  }
  pending.Commit();
}

std::string ReadTextFile(const std::string& path) {
  std::ifstream stream(path, std::ios::binary);
  if (!stream) {
    ThrowInvalid(path + ": cannot open (" + std::string(std::strerror(errno)) + ")");
  }
  std::ostringstream buffer;
  buffer << stream.rdbuf();
  if (stream.bad()) ThrowInvalid(path + ": read failed");
  return buffer.str();
}

}  // namespace aos
