#include "aos/util/process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "aos/util/error.h"

extern char** environ;

namespace aos {
namespace {

bool IsExecutableFile(const std::string& path) {
  struct stat info;
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode) &&
         ::access(path.c_str(), X_OK) == 0;
}

// The file that exec would run for `program`, or "" if none.
std::string Resolve(const std::string& program) {
  if (program.empty()) return "";
  if (program.find('/') != std::string::npos) return IsExecutableFile(program) ? program : "";
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/local/bin:/usr/bin:/bin";
  size_t start = 0;
  while (start <= dirs.size()) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string dir = end > start ? dirs.substr(start, end - start) : ".";
    const std::string candidate = dir + "/" + program;
    if (IsExecutableFile(candidate)) return candidate;
    start = end + 1;
  }
  return "";
}

// Waits for the child; returns its status as documented.
int Reap(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return 255;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 255;
}

}  // namespace

bool ProgramExists(const std::string& program) { return !Resolve(program).empty(); }

int RunProcess(const std::vector<std::string>& argv,
               const std::function<void(const std::string& line)>& on_line,
               const std::function<bool()>& cancelled) {
  if (argv.empty()) ThrowInvalid("RunProcess: no program given");
  const std::string program = Resolve(argv[0]);
  if (program.empty()) {
    ThrowInvalid(argv[0] + ": not found (not an executable file, nor on PATH)");
  }
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    ThrowInvalid(argv[0] + ": cannot create a pipe: " + std::strerror(errno));
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  // dup2 clears close-on-exec on the copies, so the child keeps exactly stdout and stderr.
  posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
  // The child starts with default signal handling (a parent that ignores SIGINT or SIGPIPE
  // must not pass that on) and in its own process group, so a terminal's Ctrl-C reaches the
  // parent, which then stops the child itself.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGPIPE);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGHUP);
  posix_spawnattr_setsigdefault(&attributes, &defaults);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setpgroup(&attributes, 0);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK |
                                            POSIX_SPAWN_SETPGROUP);
  std::vector<char*> args;
  for (const std::string& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, program.c_str(), &actions, &attributes, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  ::close(fds[1]);
  if (spawned != 0) {
    ::close(fds[0]);
    ThrowInvalid(argv[0] + ": cannot start: " + std::strerror(spawned));
  }

  // From here on every way out closes the pipe and reaps the child (killing it first when it
  // may still run), so no process or descriptor is left behind.
  int status = -1;  // the child's exit status once reaped
  const auto stop_child = [&](bool gently) {
    if (status >= 0) return;
    if (gently) {
      ::kill(pid, SIGTERM);
      for (int i = 0; i < 20; ++i) {
        int raw = 0;
        if (::waitpid(pid, &raw, WNOHANG) == pid) {
          status = 0;
          return;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    }
    ::kill(pid, SIGKILL);
    Reap(pid);
    status = 0;
  };
  std::string pending;
  const auto emit = [&](bool flush) {
    size_t start = 0;
    for (size_t i = 0; i < pending.size(); ++i) {
      if (pending[i] == '\n' || pending[i] == '\r') {
        if (on_line && i > start) on_line(pending.substr(start, i - start));
        start = i + 1;
      }
    }
    pending.erase(0, start);
    if (flush && !pending.empty()) {
      if (on_line) on_line(pending);
      pending.clear();
    }
  };
  bool cancel = false;
  try {
    char buffer[4096];
    for (;;) {
      if (cancelled && cancelled()) {
        cancel = true;
        break;
      }
      pollfd poll_fd{fds[0], POLLIN, 0};
      const int ready = ::poll(&poll_fd, 1, 100);
      if (ready < 0) {
        if (errno == EINTR) continue;
        ThrowInvalid(argv[0] + ": cannot read its output: " + std::strerror(errno));
      }
      if (ready == 0) {
        // The child may have exited while something it started still holds the pipe open.
        int raw = 0;
        if (::waitpid(pid, &raw, WNOHANG) == pid) {
          status = WIFEXITED(raw) ? WEXITSTATUS(raw) : WIFSIGNALED(raw) ? 128 + WTERMSIG(raw) : 255;
          // Drain what is already buffered, then stop.
          for (;;) {
            pollfd again{fds[0], POLLIN, 0};
            if (::poll(&again, 1, 0) <= 0) break;
            const ssize_t n = ::read(fds[0], buffer, sizeof(buffer));
            if (n <= 0) break;
            pending.append(buffer, static_cast<size_t>(n));
          }
          break;
        }
        continue;
      }
      const ssize_t n = ::read(fds[0], buffer, sizeof(buffer));
      if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      if (n <= 0) break;  // end of output: the child closed its side (normally on exit)
      pending.append(buffer, static_cast<size_t>(n));
      emit(false);
    }
    if (!cancel) emit(true);
  } catch (...) {  // a failing read or a throwing callback must not leave the child running
    ::close(fds[0]);
    stop_child(/*gently=*/false);
    throw;
  }
  ::close(fds[0]);
  if (cancel) {
    stop_child(/*gently=*/true);
    throw Cancelled();
  }
  return status >= 0 ? status : Reap(pid);
}

}  // namespace aos
