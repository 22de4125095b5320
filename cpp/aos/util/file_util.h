#pragma once
// Safe input and output files.
//
// Inputs: every reader accepts regular files only (after following links): a FIFO would block
// the reader forever and a device such as /dev/zero never ends, so both are refused before they
// are opened for reading, and text files are read with a size bound.
//
// Outputs are written under a temporary name in the destination folder and renamed into place
// only when complete, so a failure never leaves a half-written file, and an output path that
// names an input file (or a file inside an input folder; links resolved) is refused before
// anything is written.
#include <cstdint>
#include <string>
#include <vector>

namespace aos {

// Largest text file (JSON, CSV, COLMAP text model) any reader accepts: 1 GiB. A larger file is
// refused with its size rather than read into memory.
inline constexpr uint64_t kMaxTextFileBytes = uint64_t{1} << 30;

// Throws std::invalid_argument "<path>: <what>: ..." unless `path` names an existing regular
// file (links followed): a folder, FIFO, socket or device is refused by kind. Returns its size in
// bytes.
uint64_t CheckRegularFile(const std::string& path, const std::string& what = "input file");

// A pending output file. TempPath() is where to write (same folder and extension as the final
// path, so format detection by extension still works). Commit() renames it to the final path;
// the destructor removes the temporary file if Commit() was never called.
class PendingFile {
 public:
  explicit PendingFile(std::string final_path);
  ~PendingFile();
  PendingFile(const PendingFile&) = delete;
  PendingFile& operator=(const PendingFile&) = delete;
  PendingFile(PendingFile&& other) noexcept;
  PendingFile& operator=(PendingFile&&) = delete;

  const std::string& TempPath() const { return temp_path_; }
  const std::string& FinalPath() const { return final_path_; }
  // Renames the temporary file into place. Throws std::invalid_argument naming the file on failure.
  void Commit();

 private:
  std::string final_path_;
  std::string temp_path_;
  bool committed_ = false;
};

// Removes the temporary file or folder of every PendingFile and PendingFolder that is neither
// committed nor destroyed: for a process that must end at once without running destructors (the
// CLI ends the work this way when it has not stopped 1.5 s after SIGTERM/SIGINT; progress_bar.h).
void RemovePendingOutputs();

// The process's cancellation source as outputs see it: when set and it answers true,
// PendingFile::Commit, CommitTogether and PendingFolder::Commit throw aos::Cancelled instead of
// moving a finished output into place, so a signal that arrives while an output is being written
// (after the command's last progress poll) still leaves no output. The CLI sets its signal flag.
void SetCommitCancelled(bool (*cancelled)());
// Throws aos::Cancelled when that source is set and answers true: for writers to poll between
// parts of a long write (WriteImage polls between bands of rows).
void ThrowIfOutputCancelled();

// Moves several finished files into place together: files already at the final paths are first
// renamed to backups, then every temporary file is renamed; if any rename fails, the new files are
// removed and the backups restored, so either all outputs are new or none changed. Throws
// std::invalid_argument naming the file that failed.
void CommitTogether(const std::vector<PendingFile*>& files);

// Throws std::invalid_argument if `output_path` is the same file as any of `input_paths`
// (compared by device and inode, so symbolic and hard links are resolved), or lies in the tree of
// an input that is a folder and is the same file as one in it, or if its folder does not exist.
// Every command checks each output against every input it reads with this one rule.
void CheckOutputPath(const std::string& output_path, const std::vector<std::string>& input_paths,
                     const std::string& what = "output");

// Refuses an output folder that exists and is not an empty folder (nothing is overwritten), or
// whose parent folder is missing; the errors name `output_dir`. PendingFolder checks the same;
// callers check first to fail before a long computation.
void CheckOutputFolder(const std::string& output_dir);

// A new private folder (mode 0700, a name no one can guess): `prefix` + 6 characters in the
// temporary directory ($TMPDIR, else /tmp). The caller removes it. Throws naming `what`.
std::string MakePrivateTempFolder(const std::string& prefix, const std::string& what);

// A pending output folder: the contents are written into a hidden temporary sibling
// (TempPath()), and Commit() renames it to the final path. The constructor refuses a final path
// that exists and is not an empty folder (nothing is overwritten) or whose parent folder is
// missing, naming `output_dir`; the destructor removes the temporary folder unless committed.
class PendingFolder {
 public:
  explicit PendingFolder(const std::string& output_dir);
  ~PendingFolder();
  PendingFolder(const PendingFolder&) = delete;
  PendingFolder& operator=(const PendingFolder&) = delete;

  const std::string& TempPath() const { return temp_path_; }
  void Commit();

 private:
  std::string output_dir_;
  std::string final_path_;
  std::string temp_path_;
  bool committed_ = false;
};

// Writes `text` to `path` atomically (temporary file, then rename).
void WriteTextFileAtomic(const std::string& path, const std::string& text);

// Natural order of names (frame files, view names): runs of ASCII digits compare as numbers
// ("2.png" < "10.png" < "frame_10b.png"), every other character by its byte; numbers of equal
// value with more leading zeros come first ("02" < "2"), and names equal in that order fall back
// to byte order, so the order is total. Frames named by an unpadded counter (grabbed from video,
// most capture apps) come out in capture order.
bool NaturalLess(const std::string& a, const std::string& b);
// Sorts `names` in natural order (NaturalLess).
void SortNaturally(std::vector<std::string>* names);

// Reads a whole file (regular files only, at most `max_bytes`); throws std::invalid_argument
// naming the file if it cannot be read, is not a regular file or is larger. With `offset`, the
// bytes from there on (a growing log read again; "" when the file is no longer than that; the
// file as a whole is held to `max_bytes`).
std::string ReadTextFile(const std::string& path, uint64_t max_bytes = kMaxTextFileBytes,
                         uint64_t offset = 0);

}  // namespace aos
