// Child processes for multi-process tests: started with their output in a log file,
// stopped (gently or with SIGKILL) and always reaped, bounded in time.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cpvs::testing {

class ChildProcess {
 public:
  /// Starts `argv` with stdout and stderr appended to `logPath`.
  ChildProcess(const std::vector<std::string>& argv, const std::string& logPath) : log_(logPath) {
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      int fd = open(logPath.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
      }
      setenv("GRPC_ARG_ENABLE_HTTP_PROXY", "0", 1);
      unsetenv("http_proxy");
      unsetenv("https_proxy");
      unsetenv("HTTP_PROXY");
      unsetenv("HTTPS_PROXY");
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() { stop(SIGKILL); }

  /// Sends `sig` and reaps the process (SIGKILL after 10 s if it does not exit).
  /// Returns the exit status, or -signal.
  int stop(int sig = SIGTERM) {
    if (pid_ <= 0) return status_;
    kill(pid_, sig);
    return wait(10.0);
  }

  /// Waits up to `seconds` for the process to exit by itself; kills it after that.
  int wait(double seconds) {
    if (pid_ <= 0) return status_;
    auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    int raw = 0;
    while (waitpid(pid_, &raw, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > end) {
        kill(pid_, SIGKILL);
        waitpid(pid_, &raw, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    pid_ = -1;
    status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : -WTERMSIG(raw);
    return status_;
  }

  pid_t pid() const { return pid_; }

  bool running() {
    if (pid_ <= 0) return false;
    int raw = 0;
    if (waitpid(pid_, &raw, WNOHANG) == 0) return true;
    pid_ = -1;
    status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : -WTERMSIG(raw);
    return false;
  }

  std::string log() const {
    std::ifstream in(log_);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

  /// Waits until the log holds `text`; false after `seconds` or when the process ended.
  bool waitForLog(const std::string& text, double seconds) {
    auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (log().find(text) != std::string::npos) return true;
      if (!running()) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }

 private:
  pid_t pid_ = -1;
  int status_ = -1;
  std::string log_;
};

/// What a shell command printed and how it exited (-1: it did not exit normally).
struct CommandResult {
  int status = -1;
  std::string out;
};

/// Runs a shell command line to its end and collects its standard output (add `2>&1` to
/// collect its errors too). Bound it with coreutils' `timeout` in the line itself.
CommandResult runShell(const std::string& line);

/// Waits until `path` exists and is not empty; "" after `seconds`.
std::string waitForFile(const std::string& path, double seconds);

}  // namespace cpvs::testing
