// The util layer's contracts for bad input (issue 13): one-line valid-UTF-8 messages that name the
// user's paths, regular files only with bounded reads, outputs never an input (links and folders
// resolved), JSON errors with their key path, and the memory budget.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/json_file.h"
#include "aos/util/memory.h"
#include "aos/util/timer.h"
#include "error_of.h"
#include "temp_folder.h"

namespace aos {
namespace {

using test_util::ErrorOf;
using testing::HasSubstr;
using testing::Not;
namespace fs = std::filesystem;

TEST(Errors, MessagesAreOneLineOfValidUtf8) {
  EXPECT_EQ(OneLine("a.png: cannot read image (PNG read error\nPNG library error)\n"),
            "a.png: cannot read image (PNG read error; PNG library error)");
  EXPECT_EQ(OneLine("x\r\n\n  y"), "x; y");
  EXPECT_EQ(OneLine("name\xff\x01 caf\xc3\xa9"), "name\\xFF\\x01 caf\xc3\xa9");
  EXPECT_TRUE(IsValidUtf8("caf\xc3\xa9 \xf0\x9f\x98\x80"));
  EXPECT_FALSE(IsValidUtf8("\xc3"));          // truncated sequence
  EXPECT_FALSE(IsValidUtf8("\xc0\xaf"));      // overlong '/'
  EXPECT_FALSE(IsValidUtf8("\xed\xa0\x80"));  // a UTF-16 surrogate
  EXPECT_FALSE(IsValidUtf8("\xf4\x90\x80\x80"));  // past U+10FFFF
  const std::string message = ErrorOf([] { ThrowInvalid("bad\nbyte \xfe"); });
  EXPECT_EQ(message, "bad; byte \\xFE");
}

class FilesTest : public testing_util::TempFolderTest {
 protected:
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(Path(name), std::ios::binary) << text;
    return Path(name);
  }
};

TEST_F(FilesTest, ErrorsNameTheUsersPathNotTheTemporaryFile) {
  PendingFile pending(Path("out.png"));
  EXPECT_EQ(ErrorOf([&] { ThrowInvalid(pending.TempPath() + ": cannot write image"); }),
            Path("out.png") + ": cannot write image");
  // A temporary file of a temporary file maps back in two steps.
  PendingFile inner(pending.TempPath());
  EXPECT_EQ(ErrorOf([&] { ThrowInvalid(inner.TempPath() + ": disk full"); }),
            Path("out.png") + ": disk full");
  PendingFolder folder(Path("stack"));
  EXPECT_EQ(ErrorOf([&] { ThrowInvalid(folder.TempPath() + "/slice_0000.tif: disk full"); }),
            Path("stack") + "/slice_0000.tif: disk full");
}

TEST_F(FilesTest, OnlyRegularFilesAreRead) {
  ASSERT_EQ(::mkfifo(Path("fifo").c_str(), 0600), 0);
  EXPECT_THAT(ErrorOf([&] { ReadTextFile(Path("fifo")); }),
              HasSubstr(Path("fifo") + ": input file: is a FIFO (named pipe)"));
  EXPECT_THAT(ErrorOf([&] { ReadTextFile("/dev/zero"); }),
              HasSubstr("/dev/zero: input file: is a character device"));
  EXPECT_THAT(ErrorOf([&] { ReadTextFile(dir_.string()); }), HasSubstr("is a folder"));
  EXPECT_THAT(ErrorOf([&] { CheckRegularFile(Path("fifo"), "scene"); }),
              HasSubstr("fifo: scene: is a FIFO"));
  EXPECT_THAT(ErrorOf([&] { ReadTextFile(Path("missing.json")); }), HasSubstr("file not found"));
  // Bounded: a file over the limit is refused with its size; at the limit it is read.
  const std::string path = Write("big.json", std::string(1000, 'x'));
  EXPECT_THAT(ErrorOf([&] { ReadTextFile(path, 999); }),
              HasSubstr("big.json: file of 1000 bytes is larger than aos reads (999 bytes)"));
  EXPECT_EQ(ReadTextFile(path, 1000).size(), 1000u);
  EXPECT_EQ(ReadTextFile(Write("empty.json", "")), "");
}

TEST_F(FilesTest, AnOutputIsNeverAnInputThroughLinksOrFolders) {
  fs::create_directories(dir_ / "model" / "sub");
  const std::string images = Write("model/images.txt", "1");
  const std::string deep = Write("model/sub/points.txt", "2");
  fs::create_symlink(images, dir_ / "link.txt");
  fs::create_hard_link(deep, dir_ / "hard.txt");
  const std::vector<std::string> inputs{Path("model"), Path("other.csv")};
  for (const std::string& output : {images, deep, Path("link.txt"), Path("hard.txt")}) {
    EXPECT_THAT(ErrorOf([&] { CheckOutputPath(output, inputs); }),
                HasSubstr("refusing to overwrite an input file"))
        << output;
  }
  // The same file given as a file input, through a link.
  EXPECT_THAT(ErrorOf([&] { CheckOutputPath(Path("link.txt"), {images}); }),
              HasSubstr("it is the same file as"));
  // A new file, even inside an input folder, and an unrelated existing file are fine.
  EXPECT_EQ(ErrorOf([&] { CheckOutputPath(Path("model/new.json"), inputs); }), "no error");
  const std::string unrelated = Write("unrelated.json", "3");
  EXPECT_EQ(ErrorOf([&] { CheckOutputPath(unrelated, inputs); }), "no error");
}

TEST(Json, ErrorsNameTheFileAndTheKeyPath) {
  EXPECT_EQ(ErrorOf([] { ParseJsonText(R"({"views": [{}, {"t": [1, 1e999]}]})", "lf.json"); }),
            "lf.json: /views/1/t/1: not valid JSON (number overflow parsing '1e999')");
  EXPECT_THAT(ErrorOf([] { ParseJsonText("{\"a\": [1, 2,", "lf.json"); }),
              HasSubstr("lf.json: /a/2: not valid JSON (parse error at line 1"));
  EXPECT_THAT(ErrorOf([] { ParseJsonText("{\"a\": \"\xff\"}", "x.json"); }),
              HasSubstr("x.json: /a: not valid JSON (parse error"));
  // A value of the wrong type, found while reading the fields: the key path from the library.
  const nlohmann::json document = ParseJsonText(R"({"camera": {"format": 3}})", "cam.json");
  const std::string message = ErrorOf([&] {
    WithJsonErrorsNamed("cam.json", [&] { return document["camera"]["format"].get<std::string>(); });
  });
  EXPECT_EQ(message, "cam.json: /camera/format: type must be string, but is number");
  EXPECT_THAT(message, Not(HasSubstr("json.exception")));
}

TEST(Memory, TheBudgetComesFromTheEnvironmentOrTheMachine) {
  EXPECT_EQ(SaturatingProduct({65536, 65536, 8}), uint64_t{1} << 35);
  EXPECT_EQ(SaturatingProduct({uint64_t{1} << 40, uint64_t{1} << 40}),
            std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(FormatBytes(uint64_t{3} << 29), "1.5 GiB");
  EXPECT_EQ(FormatBytes(128u << 20), "128 MiB");
  EXPECT_GT(MemoryBudgetBytes(), uint64_t{64} << 20);
  ::setenv("AOS_MEMORY_LIMIT_MB", "100", 1);
  EXPECT_EQ(MemoryBudgetBytes(), uint64_t{100} << 20);
  EXPECT_EQ(ErrorOf([] { CheckMemoryBudget(uint64_t{100} << 20, "w", "d"); }), "no error");
  EXPECT_EQ(ErrorOf([] { CheckMemoryBudget((uint64_t{100} << 20) + 1, "width/height: 9 x 9", "x"); }),
            "width/height: 9 x 9: needs 100 MiB of memory (x) but only 100 MiB are available "
            "(the limit AOS_MEMORY_LIMIT_MB); make it smaller");
  ::setenv("AOS_MEMORY_LIMIT_MB", "-4", 1);
  EXPECT_THAT(ErrorOf([] { MemoryBudgetBytes(); }), HasSubstr("AOS_MEMORY_LIMIT_MB: expected"));
  ::unsetenv("AOS_MEMORY_LIMIT_MB");
}

TEST(Timer, CountsSecondsFromItsStartOrRestart) {
  // Orderings that hold on any machine, however loaded: a timer started 20 ms before another
  // reads at least 20 ms more (read second), and a restart starts it anew.
  const Timer first;
  EXPECT_GE(first.Seconds(), 0.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  Timer second;
  const double second_reads = second.Seconds();
  const double first_reads = first.Seconds();
  EXPECT_GE(first_reads - second_reads, 0.02);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  Timer third;
  second.Restart();
  const double restarted_reads = second.Seconds();
  EXPECT_LE(restarted_reads, third.Seconds());
  EXPECT_GE(first.Seconds(), first_reads);
}

TEST(ReadTextFile, FromAnOffsetReadsTheRestAndStillRefusesWhatItRefuses) {
  const std::string folder = MakePrivateTempFolder("aos-read-", "test");
  const std::string path = folder + "/log.csv";
  { std::ofstream(path) << "time,x\n1,2\n"; }
  EXPECT_EQ(ReadTextFile(path, kMaxTextFileBytes, 7), "1,2\n");
  EXPECT_EQ(ReadTextFile(path, kMaxTextFileBytes, 11), "");  // no longer than the offset
  EXPECT_EQ(ReadTextFile(path, kMaxTextFileBytes, 99), "");
  EXPECT_THAT(ErrorOf([&] { ReadTextFile(path, 5, 7); }), ::testing::HasSubstr("larger"));
  const std::string fifo = folder + "/fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_FALSE(ErrorOf([&] { ReadTextFile(fifo, kMaxTextFileBytes, 3); }).empty());
  std::filesystem::remove_all(folder);
}

TEST(PrivateTempFolder, IsNewPrivateAndInTmpdir) {
  const std::filesystem::path base = std::filesystem::temp_directory_path() / "aos-tmpdir-test";
  std::filesystem::create_directories(base);
  const char* old = std::getenv("TMPDIR");
  const std::string saved = old != nullptr ? old : "";
  ::setenv("TMPDIR", base.c_str(), 1);
  const std::string a = MakePrivateTempFolder("aos-x-", "test");
  const std::string b = MakePrivateTempFolder("aos-x-", "test");
  if (old != nullptr) ::setenv("TMPDIR", saved.c_str(), 1); else ::unsetenv("TMPDIR");
  EXPECT_NE(a, b);
  EXPECT_EQ(std::filesystem::path(a).parent_path(), base);
  EXPECT_EQ(std::filesystem::path(a).filename().string().rfind("aos-x-", 0), 0u);
  struct stat info {};
  ASSERT_EQ(::stat(a.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0700u);
  std::filesystem::remove_all(base);
}

}  // namespace
}  // namespace aos
