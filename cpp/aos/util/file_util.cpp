#include "aos/util/file_util.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>
#include <system_error>

#include <fcntl.h>
#include <sys/stat.h>
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

// The temporary paths of the PendingFiles and PendingFolders alive and not committed, for
// RemovePendingOutputs.
std::mutex& PendingMutex() {
  static std::mutex mutex;
  return mutex;
}
std::set<std::string>& PendingPaths() {
  static std::set<std::string> paths;
  return paths;
}
void AddPending(const std::string& path) {
  std::lock_guard<std::mutex> lock(PendingMutex());
  PendingPaths().insert(path);
}
void ErasePending(const std::string& path) {
  std::lock_guard<std::mutex> lock(PendingMutex());
  PendingPaths().erase(path);
}

}  // namespace

namespace {
std::atomic<bool (*)()> g_commit_cancelled{nullptr};
void ThrowIfCommitCancelled() {
  bool (*cancelled)() = g_commit_cancelled.load();
  if (cancelled != nullptr && cancelled()) throw Cancelled();
}
}  // namespace

void SetCommitCancelled(bool (*cancelled)()) { g_commit_cancelled.store(cancelled); }

void ThrowIfOutputCancelled() { ThrowIfCommitCancelled(); }

void RemovePendingOutputs() {
  std::lock_guard<std::mutex> lock(PendingMutex());
  for (const std::string& path : PendingPaths()) {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
  PendingPaths().clear();
}

PendingFile::PendingFile(std::string final_path)
    : final_path_(std::move(final_path)), temp_path_(MakeTempPath(final_path_)) {
  RegisterPathAlias(temp_path_, final_path_);
  AddPending(temp_path_);
}

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
    ErasePending(temp_path_);
  }
}

void PendingFile::Commit() {
  ThrowIfCommitCancelled();
  std::error_code error;
  fs::rename(temp_path_, final_path_, error);
  if (error) {
    ThrowInvalid(final_path_ + ": cannot move the finished file into place (" + error.message() +
                 ")");
  }
  committed_ = true;
  ErasePending(temp_path_);
}

void CommitTogether(const std::vector<PendingFile*>& files) {
  ThrowIfCommitCancelled();
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

namespace {

const char* FileKind(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

[[noreturn]] void RefuseKind(const std::string& path, const std::string& what, mode_t mode) {
  ThrowInvalid(path + ": " + what + ": is " + FileKind(mode) + ", expected a regular file");
}

// Device and inode of a path (links followed), or false if it cannot be stat'ed.
bool FileId(const std::string& path, dev_t* device, ino_t* inode) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return false;
  *device = info.st_dev;
  *inode = info.st_ino;
  return true;
}

// Whether the regular file (device, inode) is a file in the tree of `folder` (bounded walk: an
// input folder of more than a million entries is not searched further).
bool FolderHolds(const fs::path& folder, dev_t device, ino_t inode) {
  std::error_code error;
  fs::recursive_directory_iterator it(folder, fs::directory_options::skip_permission_denied,
                                      error);
  int64_t visited = 0;
  for (; !error && it != fs::recursive_directory_iterator(); it.increment(error)) {
    if (++visited > 1000000) break;
    dev_t entry_device;
    ino_t entry_inode;
    if (FileId(it->path().string(), &entry_device, &entry_inode) && entry_device == device &&
        entry_inode == inode) {
      return true;
    }
  }
  return false;
}

}  // namespace

uint64_t CheckRegularFile(const std::string& path, const std::string& what) {
  if (path.empty()) ThrowInvalid(what + ": the path is empty");
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) {
    const int code = errno;
    if (code == ENOENT) ThrowInvalid(path + ": " + what + " not found");
    ThrowInvalid(path + ": " + what + ": " + std::strerror(code));
  }
  if (!S_ISREG(info.st_mode)) RefuseKind(path, what, info.st_mode);
  return static_cast<uint64_t>(info.st_size);
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
  dev_t device;
  ino_t inode;
  if (!FileId(output_path, &device, &inode)) return;  // nothing there: it is no input
  for (const std::string& input : input_paths) {
    if (input.empty()) continue;
    dev_t input_device;
    ino_t input_inode;
    if (!FileId(input, &input_device, &input_inode)) continue;
    if (input_device == device && input_inode == inode) {
      ThrowInvalid(output_path + ": " + what +
                   ": refusing to overwrite an input file (it is the same file as " + input + ")");
    }
    if (fs::is_directory(input, error) && FolderHolds(input, device, inode)) {
      ThrowInvalid(output_path + ": " + what +
                   ": refusing to overwrite an input file (it is a file of the input folder " +
                   input + ")");
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

std::string ReadTextFile(const std::string& path, uint64_t max_bytes, uint64_t offset) {
  // Opened without blocking (a FIFO swapped in after a check would block a plain open), then
  // checked on the open descriptor.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int code = errno;
    ThrowInvalid(path + ": cannot open (" +
                 (code == ENOENT ? std::string("file not found") : std::strerror(code)) + ")");
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat info {};
  if (::fstat(fd, &info) != 0) ThrowInvalid(path + ": cannot read (" + std::strerror(errno) + ")");
  if (!S_ISREG(info.st_mode)) RefuseKind(path, "input file", info.st_mode);
  const uint64_t size = static_cast<uint64_t>(info.st_size);
  const auto too_large = [&](uint64_t bytes) {
    ThrowInvalid(path + ": file of " + std::to_string(bytes) + " bytes is larger than aos reads (" +
                 std::to_string(max_bytes) + " bytes)");
  };
  if (size > max_bytes) too_large(size);
  if (offset >= size) return std::string();
  if (offset > 0 && ::lseek(fd, static_cast<off_t>(offset), SEEK_SET) < 0) {
    ThrowInvalid(path + ": cannot read (" + std::strerror(errno) + ")");
  }
  max_bytes -= offset;  // what may follow the offset
  std::string text;
  text.resize(static_cast<size_t>(size - offset));
  size_t done = 0;
  while (true) {
    if (done == text.size()) {
      // The file may have grown since fstat: read on, still bounded.
      if (text.size() >= max_bytes) {
        char probe;
        const ssize_t more = ::read(fd, &probe, 1);
        if (more > 0) too_large(text.size() + 1);
        break;
      }
      text.resize(std::min<uint64_t>(max_bytes, text.size() + 65536));
    }
    const ssize_t n = ::read(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      ThrowInvalid(path + ": read failed (" + std::strerror(errno) + ")");
    }
    if (n == 0) break;
    done += static_cast<size_t>(n);
  }
  text.resize(done);
  return text;
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

std::string MakePrivateTempFolder(const std::string& prefix, const std::string& what) {
  std::string pattern;
  try {
    pattern = (fs::temp_directory_path() / (prefix + "XXXXXX")).string();
  } catch (const fs::filesystem_error& error) {
    ThrowInvalid(what + ": no temporary directory ($TMPDIR): " + error.what());
  }
  if (::mkdtemp(pattern.data()) == nullptr) {
    ThrowInvalid(what + ": cannot make a temporary folder " + pattern + ": " + std::strerror(errno));
  }
  return pattern;
}

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
  std::string shown = output_dir;
  while (shown.size() > 1 && shown.back() == '/') shown.pop_back();
  RegisterPathAlias(temp_path_, shown);
  AddPending(temp_path_);
}

PendingFolder::~PendingFolder() {
  if (!committed_ && !temp_path_.empty()) {
    std::error_code ignored;
    fs::remove_all(temp_path_, ignored);
    ErasePending(temp_path_);
  }
}

void PendingFolder::Commit() {
  ThrowIfCommitCancelled();
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
  ErasePending(temp_path_);
}

namespace {

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

// -1, 0, 1: a against b in natural order, without the byte-order tie-break.
int NaturalCompare(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  int zeros = 0;  // the first difference in leading zeros of equal numbers
  while (i < a.size() && j < b.size()) {
    if (IsDigit(a[i]) && IsDigit(b[j])) {
      size_t ai = i, bj = j;
      while (ai < a.size() && a[ai] == '0') ++ai;
      while (bj < b.size() && b[bj] == '0') ++bj;
      size_t ae = ai, be = bj;
      while (ae < a.size() && IsDigit(a[ae])) ++ae;
      while (be < b.size() && IsDigit(b[be])) ++be;
      if (ae - ai != be - bj) return ae - ai < be - bj ? -1 : 1;  // more digits: larger
      const int digits = a.compare(ai, ae - ai, b, bj, be - bj);
      if (digits != 0) return digits < 0 ? -1 : 1;
      if (zeros == 0 && ai - i != bj - j) zeros = ai - i > bj - j ? -1 : 1;
      i = ae;
      j = be;
      continue;
    }
    if (a[i] != b[j]) {
      return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]) ? -1 : 1;
    }
    ++i;
    ++j;
  }
  if (i < a.size() || j < b.size()) return i < a.size() ? 1 : -1;  // a prefix comes first
  return zeros;
}

}  // namespace

bool NaturalLess(const std::string& a, const std::string& b) {
  const int order = NaturalCompare(a, b);
  return order != 0 ? order < 0 : a < b;
}

void SortNaturally(std::vector<std::string>* names) {
  std::sort(names->begin(), names->end(), NaturalLess);
}

}  // namespace aos
