#pragma once
// Shared by the libFuzzer harnesses (tests/fuzz/*_fuzzer.cpp) and the seed writer
// (make_seeds.cpp).
//
// The readers under test take file paths, so a harness writes each input into a work folder of
// its own process (/dev/shm/aos-fuzz-<harness>-<pid>/, else the system temp folder; removed at
// exit) and calls the reader on it. The work folder also holds fixture files the inputs may refer
// to (tiny frames, slice images, a texture), written once at start-up by WriteFixtures with
// aos's own writer, so a reproducer needs nothing but the harness binary.
//
// The contract checked (util/error.h): bad input throws std::invalid_argument whose message is
// one line of valid UTF-8 (pybind11 turns it into ValueError and must be able to make a str of
// it). Any other exception escaping a reader (std::runtime_error, nlohmann::json::exception,
// std::filesystem::filesystem_error, std::out_of_range, std::bad_alloc, ...) would reach Python
// as RuntimeError or worse: the harness prints it and aborts, so libFuzzer records the input as a
// crash. Memory errors (ASan), undefined behaviour (UBSan), leaks (LSan), allocations beyond
// -malloc_limit_mb, and inputs slower than -timeout are libFuzzer's own findings.
//
// The memory budget of the core (util/memory.h) is set to AOS_FUZZ_MEMORY_LIMIT_MB (default 1024
// MiB) through AOS_MEMORY_LIMIT_MB, half of the -malloc_limit_mb / -rss_limit_mb of 2048 that
// tools/run_sanitizers.sh gives libFuzzer: a reader that checks its budget before allocating
// never reaches the limit, so an out-of-memory finding is an allocation the budget missed.
#include <cxxabi.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>
#include <typeinfo>

#include "aos/image/image.h"
#include "aos/image/image_io.h"

namespace aos_fuzz {

namespace fs = std::filesystem;

// Width and height of every fixture frame (seeds name cameras of this size).
inline constexpr int kFrameWidth = 8;
inline constexpr int kFrameHeight = 6;

// Separates the three files of a COLMAP model (cameras, images, points3D) in one fuzz input.
inline constexpr const char kFileSeparator[] = "#AOS-NEXT-FILE#";

inline std::string Demangle(const char* name) {
  int status = 0;
  char* text = abi::__cxa_demangle(name, nullptr, nullptr, &status);
  std::string result = status == 0 && text != nullptr ? text : name;
  std::free(text);
  return result;
}

// Whether `text` is valid UTF-8 (no overlong forms, surrogates or code points past U+10FFFF).
// Written here rather than taken from the core so the check does not trust the code it checks.
inline bool IsValidUtf8(const std::string& text) {
  size_t i = 0;
  const size_t n = text.size();
  while (i < n) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      ++i;
      continue;
    }
    int extra = 0;
    uint32_t code = 0, min = 0;
    if (c >= 0xC2 && c <= 0xDF) {
      extra = 1, code = c & 0x1F, min = 0x80;
    } else if (c >= 0xE0 && c <= 0xEF) {
      extra = 2, code = c & 0x0F, min = 0x800;
    } else if (c >= 0xF0 && c <= 0xF4) {
      extra = 3, code = c & 0x07, min = 0x10000;
    } else {
      return false;
    }
    if (i + extra >= n) return false;  // the sequence runs past the end
    for (int k = 1; k <= extra; ++k) {
      const unsigned char d = static_cast<unsigned char>(text[i + k]);
      if ((d & 0xC0) != 0x80) return false;
      code = (code << 6) | (d & 0x3F);
    }
    if (code < min || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return false;
    i += extra + 1;
  }
  return true;
}

[[noreturn]] inline void Finding(const std::string& call, const std::string& what) {
  std::fprintf(stderr, "\n==aos-fuzz== FINDING in %s: %s\n", call.c_str(), what.c_str());
  std::fflush(stderr);
  std::abort();
}

// AOS_FUZZ_VERBOSE=1 prints each call's outcome (to see what the seeds reach).
inline bool Verbose() {
  static const bool verbose = std::getenv("AOS_FUZZ_VERBOSE") != nullptr &&
                              std::string(std::getenv("AOS_FUZZ_VERBOSE")) != "0";
  return verbose;
}

// Runs `read`; returns true when it returned, false when it threw std::invalid_argument with a
// proper message. Anything else is a finding (abort). `call` names the reader in the report.
template <class Read>
bool Expect(const char* call, Read&& read) {
  try {
    read();
    if (Verbose()) std::fprintf(stderr, "aos-fuzz: %s: ok\n", call);
    return true;
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    if (Verbose()) std::fprintf(stderr, "aos-fuzz: %s: refused: %s\n", call, message.c_str());
    if (message.empty()) Finding(call, "std::invalid_argument with an empty message");
    if (message.find_first_of("\r\n") != std::string::npos) {
      Finding(call, "std::invalid_argument message spans several lines: " + message);
    }
    if (!IsValidUtf8(message)) {
      Finding(call, "std::invalid_argument message is not valid UTF-8 (Python cannot make a "
                    "str of it): " + message);
    }
    return false;
  } catch (const std::exception& error) {
    Finding(call, "unexpected exception " + Demangle(typeid(error).name()) +
                      " (expected std::invalid_argument): " + error.what());
  } catch (...) {
    Finding(call, "unexpected exception of a type not derived from std::exception");
  }
}

inline void WriteBytes(const fs::path& path, const uint8_t* data, size_t size) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  file.close();
  if (!file) {
    std::fprintf(stderr, "aos-fuzz: cannot write %s\n", path.string().c_str());
    std::abort();
  }
}

inline void WriteText(const fs::path& path, const std::string& text) {
  WriteBytes(path, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

// A test pattern of `type` (values within the type's range; floats in [0, 1]).
inline aos::Image Pattern(int width, int height, int channels, aos::PixelType type, int seed) {
  aos::Image image(width, height, channels, type);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int code = (x * 37 + y * 91 + c * 53 + seed * 17) % 251;
        switch (type) {
          case aos::PixelType::kU8:
            image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(code);
            break;
          case aos::PixelType::kU16:
            image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(code * 257);
            break;
          case aos::PixelType::kU32:
            image.At<uint32_t>(x, y)[c] = static_cast<uint32_t>(code);
            break;
          case aos::PixelType::kF32:
            image.At<float>(x, y)[c] = static_cast<float>(code) / 250.0f;
            break;
        }
      }
    }
  }
  return image;
}

// The files that inputs may name, relative to the work folder `dir` (see make_seeds.cpp):
//   frames: views/0000.png .. views/0003.png (8-bit grey), views/rgb.png (8-bit RGB),
//           views/16bit.tif (16-bit), views/float.exr, views/photo.jpg, views/big.png (16x12);
//   JKU frames one level up, in ../images: 0000.png .. 0003.png, 0004.tiff;
//   focal stack: slice_0000.tif, slice_0001.tif (float), count_0000.tif, count_0001.tif
//           (uint32), variance_0000.tif, variance_0001.tif (float);
//   scene texture: texture.png (RGB).
inline void WriteFixtures(const fs::path& dir) {
  using aos::PixelType;
  const int w = kFrameWidth, h = kFrameHeight;
  fs::create_directories(dir / "views");
  fs::create_directories(dir.parent_path() / "images");
  for (int i = 0; i < 4; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.png", i);
    aos::WriteImage((dir / "views" / name).string(), Pattern(w, h, 1, PixelType::kU8, i));
    aos::WriteImage((dir.parent_path() / "images" / name).string(),
                    Pattern(w, h, 1, PixelType::kU8, i));
  }
  aos::WriteImage((dir.parent_path() / "images" / "0004.tiff").string(),
                  Pattern(w, h, 1, PixelType::kU8, 4));
  aos::WriteImage((dir / "views" / "rgb.png").string(), Pattern(w, h, 3, PixelType::kU8, 5));
  aos::WriteImage((dir / "views" / "16bit.tif").string(), Pattern(w, h, 1, PixelType::kU16, 6));
  aos::WriteImage((dir / "views" / "float.exr").string(), Pattern(w, h, 1, PixelType::kF32, 7));
  aos::WriteImage((dir / "views" / "photo.jpg").string(), Pattern(w, h, 1, PixelType::kU8, 8));
  aos::WriteImage((dir / "views" / "big.png").string(),
                  Pattern(2 * w, 2 * h, 1, PixelType::kU8, 9));
  for (int i = 0; i < 2; ++i) {
    char suffix[16];
    std::snprintf(suffix, sizeof(suffix), "_%04d.tif", i);
    aos::WriteImage((dir / ("slice" + std::string(suffix))).string(),
                    Pattern(w, h, 1, PixelType::kF32, 10 + i));
    aos::WriteImage((dir / ("count" + std::string(suffix))).string(),
                    Pattern(w, h, 1, PixelType::kU32, 12 + i));
    aos::WriteImage((dir / ("variance" + std::string(suffix))).string(),
                    Pattern(w, h, 1, PixelType::kF32, 14 + i));
  }
  aos::WriteImage((dir / "texture.png").string(), Pattern(16, 16, 3, PixelType::kU8, 16));
}

namespace detail {

inline fs::path& RootSlot() {
  static fs::path root;
  return root;
}

inline void RemoveRoot() {
  std::error_code ignored;
  if (!RootSlot().empty()) fs::remove_all(RootSlot(), ignored);
}

// Removes aos-fuzz-<harness>-<pid> folders of processes that are gone (a crashed run cannot
// clean up after itself).
inline void RemoveStaleRoots(const fs::path& base, const std::string& prefix) {
  std::error_code error;
  for (fs::directory_iterator it(base, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string pid_text = name.substr(prefix.size());
    if (pid_text.empty() || pid_text.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code ignored;
      fs::remove_all(it->path(), ignored);
    }
  }
}

}  // namespace detail

// The work folder of this process, created with its fixtures on first use: <root>/work, where
// <root> is /dev/shm/aos-fuzz-<harness>-<pid> (or under the system temp folder).
inline const fs::path& WorkDir(const char* harness) {
  static const fs::path work = [&] {
    std::error_code error;
    fs::path base = "/dev/shm";
    if (!fs::is_directory(base, error)) base = fs::temp_directory_path();
    const std::string prefix = std::string("aos-fuzz-") + harness + "-";
    detail::RemoveStaleRoots(base, prefix);
    detail::RootSlot() = base / (prefix + std::to_string(::getpid()));
    fs::remove_all(detail::RootSlot(), error);
    fs::create_directories(detail::RootSlot() / "work");
    std::atexit(detail::RemoveRoot);
    WriteFixtures(detail::RootSlot() / "work");
    return detail::RootSlot() / "work";
  }();
  return work;
}

// Called from each harness's LLVMFuzzerInitialize.
inline void Initialize(const char* harness) {
  const char* limit = std::getenv("AOS_FUZZ_MEMORY_LIMIT_MB");
  ::setenv("AOS_MEMORY_LIMIT_MB", limit != nullptr ? limit : "1024", 1);
  WorkDir(harness);
}

}  // namespace aos_fuzz
