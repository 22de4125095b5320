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

void CommitTogether(const std::vector<PendingFile*>& files) {
  struct Backup {
    std::string final_path, backup_path;
  };
  std::vector<Backup> backups;
  std::vector<std::string> committed;
  auto roll_back = [&] {
    std::error_code ignored;
    for (const std::string& path : committed) fs::remove(path, ignored);
    for (const Backup& backup : backups) fs::rename(backup.backup_path, backup.final_path, ignored);
  };
  try {
    for (PendingFile* file : files) {
      std::error_code error;
      if (!fs::exists(file->FinalPath(), error)) continue;
      Backup backup{file->FinalPath(), MakeTempPath(file->FinalPath())};
      fs::rename(backup.final_path, backup.backup_path, error);
      if (error) {
        ThrowInvalid(backup.final_path + ": cannot move the previous file aside (" +
                     error.message() + ")");
      }
      backups.push_back(backup);
    }
    for (PendingFile* file : files) {
      file->Commit();
      committed.push_back(file->FinalPath());
    }
  } catch (...) {
    roll_back();
    throw;
  }
  std::error_code ignored;
  for (const Backup& backup : backups) fs::remove(backup.backup_path, ignored);
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

namespace {

// The absolute final path of an output folder ("out/" -> ".../out"), checked as
// CheckOutputFolder says.
fs::path CheckedOutputFolder(const std::string& output_dir) {
  if (output_dir.empty()) ThrowInvalid("output folder: empty path");
  fs::path target = fs::absolute(fs::path(output_dir)).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  std::error_code error;
  if (fs::exists(target, error)) {
    if (!fs::is_directory(target, error)) {
      ThrowInvalid(output_dir + ": output folder: exists and is not a folder");
    }
    if (!fs::is_empty(target, error)) {
      ThrowInvalid(output_dir + ": output folder: exists and is not empty; output goes only to "
                                "a new folder or an empty one, and this is not an empty folder "
                                "(nothing is overwritten)");
    }
  }
  if (!fs::is_directory(target.parent_path(), error)) {
    ThrowInvalid(output_dir + ": output folder: the parent folder " +
                 target.parent_path().string() + " does not exist");
  }
  return target;
}

}  // namespace

void CheckOutputFolder(const std::string& output_dir) { CheckedOutputFolder(output_dir); }

PendingFolder::PendingFolder(const std::string& output_dir) : output_dir_(output_dir) {
  const fs::path target = CheckedOutputFolder(output_dir);
  const fs::path parent = target.parent_path();
  std::error_code error;
  static std::atomic<int> counter{0};
  const fs::path temp = parent / ("." + target.filename().string() + ".partial-" +
                                  std::to_string(::getpid()) + "-" + std::to_string(counter++));
  fs::create_directory(temp, error);
  if (error) {
    ThrowInvalid(output_dir + ": cannot create a temporary folder beside it (" + error.message() +
                 ")");
  }
  final_path_ = target.string();
  temp_path_ = temp.string();
}

PendingFolder::~PendingFolder() {
  if (!committed_ && !temp_path_.empty()) {
    std::error_code ignored;
    fs::remove_all(temp_path_, ignored);
  }
}

void PendingFolder::Commit() {
  std::error_code error;
  // An existing empty folder is replaced; anything else that appeared meanwhile is kept.
  if (fs::exists(final_path_, error)) {
    if (!fs::is_directory(final_path_, error) || !fs::is_empty(final_path_, error) ||
        !fs::remove(final_path_, error)) {
      ThrowInvalid(output_dir_ + ": output folder: something else was written there meanwhile; "
                                 "nothing is overwritten");
    }
  }
  fs::rename(temp_path_, final_path_, error);
  if (error) {
    ThrowInvalid(output_dir_ + ": cannot move the finished output into place (" +
                 error.message() + ")");
  }
  committed_ = true;
}

}  // namespace aos
