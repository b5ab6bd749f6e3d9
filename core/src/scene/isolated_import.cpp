#include "cpvs/scene/isolated_import.h"

#include "import_sandbox.h"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <new>
#include <thread>

#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/scene/mesh_file.h"

namespace cpvs {

namespace {

constexpr size_t kMaxErrorBytes = 16 << 10;

/// Closes a file descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  ~Fd() { reset(); }
  void reset() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

std::string firstLines(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  if (text.size() > 2000) text = text.substr(0, 2000) + "...";
  return text;
}

}  // namespace

Scene importIsolated(const std::string& path, const ImportLimits& limits, SceneStats* stats,
                     std::vector<uint8_t>* meshBytes) {
  if (limits.helper.empty()) {
    SceneStats s;
    Scene scene = loadScene(path, &s, ImportOptions{limits.selfContained});
    if (meshBytes) *meshBytes = encodeSceneMesh(scene, s);
    if (stats) *stats = s;
    return scene;
  }
  int out[2], err[2];
  if (pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  Fd outRead{out[0]}, outWrite{out[1]};
  if (pipe2(err, O_CLOEXEC) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  Fd errRead{err[0]}, errWrite{err[1]};
  // Everything the child needs is made before fork: between fork and exec it may only
  // make system calls (the coordinator has many threads).
  const std::string references = "--references";
  std::vector<char*> argv{const_cast<char*>(limits.helper.c_str()), const_cast<char*>(path.c_str())};
  if (!limits.selfContained) argv.push_back(const_cast<char*>(references.c_str()));
  argv.push_back(nullptr);
  // The child's environment is this one's, with malloc's heap on 2 MiB pages where the
  // kernel gives them (a glibc tunable; other C libraries ignore it) unless the caller set
  // tunables of its own: the importers make tens of megabytes of small blocks, and on
  // 4 KiB pages each one's first touch is a fault, which under a hypervisor was a third
  // of a city's import.
  std::vector<char*> envp;
  bool tuned = false;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    tuned = tuned || std::strncmp(*e, "GLIBC_TUNABLES=", 15) == 0;
    envp.push_back(*e);
  }
  std::string hugeHeap = "GLIBC_TUNABLES=glibc.malloc.hugetlb=1";
  if (!tuned) envp.push_back(hugeHeap.data());
  envp.push_back(nullptr);
  const rlim_t memory = rlim_t(limits.memoryBytes);
  const rlim_t cpu = rlim_t(limits.seconds) + 1;
  // vfork: the child borrows this process's memory until it runs execve, instead of
  // copying its page tables (a coordinator holding a GiB paid milliseconds per import).
  // Until then it makes system calls only, on what was made above, with every signal
  // blocked: a handler of this process (a worker's SIGTERM count) must not run in the
  // child on the shared memory. The child puts the handlers back to their defaults and
  // the mask as it was before it runs the importer (what posix_spawn does).
  sigset_t all, before;
  sigfillset(&all);
  pthread_sigmask(SIG_BLOCK, &all, &before);
  const pid_t pid = vfork();
  if (pid == 0) {
    for (int sig = 1; sig < NSIG; ++sig) {
      struct sigaction action;
      if (sigaction(sig, nullptr, &action) == 0 && action.sa_handler != SIG_IGN && action.sa_handler != SIG_DFL) {
        action.sa_handler = SIG_DFL;
        action.sa_flags = 0;
        sigaction(sig, &action, nullptr);
      }
    }
    sigprocmask(SIG_SETMASK, &before, nullptr);
    dup2(outWrite.fd, 1);
    dup2(errWrite.fd, 2);
    const int devNull = open("/dev/null", O_RDONLY);
    if (devNull >= 0) dup2(devNull, 0);
    // Nothing of the coordinator's (its database, its sockets) stays open in the child.
    syscall(SYS_close_range, 3u, ~0u, 0u);
    const rlimit as{memory, memory}, cpuTime{cpu, cpu}, noFiles{0, 0}, noCore{0, 0};
    setrlimit(RLIMIT_AS, &as);
    setrlimit(RLIMIT_CPU, &cpuTime);
    setrlimit(RLIMIT_FSIZE, &noFiles);  // it writes to its pipes only: no file at all
    setrlimit(RLIMIT_CORE, &noCore);
    execve(argv[0], argv.data(), envp.data());
    _exit(127);
  }
  const int vforkError = errno;
  pthread_sigmask(SIG_SETMASK, &before, nullptr);
  if (pid < 0) throw std::runtime_error(std::string("vfork: ") + std::strerror(vforkError));
  outWrite.reset();
  errWrite.reset();
  std::vector<uint8_t> mesh;
  std::string error;
  bool timedOut = false, tooBig = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(int64_t(limits.seconds * 1000));
  std::vector<uint8_t> buffer(1 << 16);
  while (outRead.fd >= 0 || errRead.fd >= 0) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timedOut = true;
      break;
    }
    pollfd fds[2] = {{outRead.fd, POLLIN, 0}, {errRead.fd, POLLIN, 0}};
    const int ready = poll(fds, 2, int(std::min<int64_t>(left.count(), 1000)));
    if (ready < 0 && errno != EINTR) break;
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      const ssize_t n = read(fds[i].fd, buffer.data(), buffer.size());
      if (n <= 0) {
        (i == 0 ? outRead : errRead).reset();
        continue;
      }
      if (i == 1) {
        if (error.size() < kMaxErrorBytes) error.append(reinterpret_cast<const char*>(buffer.data()), size_t(n));
      } else if (mesh.size() + size_t(n) > limits.memoryBytes) {
        tooBig = true;  // more than the importer could have held: not a mesh it made
      } else {
        mesh.insert(mesh.end(), buffer.begin(), buffer.begin() + n);
      }
    }
    if (tooBig) break;
  }
  if (timedOut || tooBig) kill(pid, SIGKILL);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const std::string limitsText = std::to_string(limits.memoryBytes >> 20) + " MiB and " +
                                 std::to_string(int64_t(limits.seconds)) + " s";
  if (timedOut) throw InputError(path + ": the import took longer than " + std::to_string(int64_t(limits.seconds)) + " s");
  if (tooBig) throw InputError(path + ": the importer sent more than " + std::to_string(limits.memoryBytes >> 20) + " MiB");
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGXCPU || sig == SIGKILL)
      throw InputError(path + ": the import used more than its " + std::to_string(int64_t(limits.seconds)) + " s of CPU time");
    throw InputError(path + ": the importer crashed on the file (signal " + std::to_string(sig) + ", " + strsignal(sig) +
                     ")");
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code == 127)
    throw std::runtime_error("cannot run the scene importer " + limits.helper +
                             " (cpvs-import comes with cpvs and cpvs-server: install it beside them)");
  if (code == 2) throw InputError(firstLines(error));
  if (code != 0) {
    if (error.find("bad_alloc") != std::string::npos || error.find("out of memory") != std::string::npos)
      throw InputError(path + ": the import needs more than its " + std::to_string(limits.memoryBytes >> 20) + " MiB");
    throw std::runtime_error("the scene importer failed (status " + std::to_string(code) + "): " + firstLines(error) +
                             " (limits " + limitsText + ")");
  }
  SceneStats s;
  Scene scene = decodeSceneMesh(mesh.data(), mesh.size(), "the importer's answer for " + path, &s);
  if (stats) *stats = s;
  if (meshBytes) *meshBytes = std::move(mesh);
  return scene;
}

std::string importProgram() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  return (self.parent_path() / "cpvs-import").string();
}

std::string requiredImportProgram(const std::string& program) {
  const std::string helper = importProgram();
  if (helper.empty() || access(helper.c_str(), X_OK) != 0)
    throw InputError("the scene importer " + (helper.empty() ? std::string("cpvs-import") : helper) +
                     " is missing: scenes are imported by it (install it beside " + program + ")");
  return helper;
}

int runImportHelper(const std::string& path, bool selfContained) {
  // Before the file is touched: whatever the importer does with it happens in the filter.
  if (const std::string why = enterImportSandbox(); !why.empty()) {
    std::cerr << "cannot enter the import sandbox: " << why << "\n";
    return 3;
  }
  try {
    // CPVS_FAILPOINT=POINT or POINT:TEXT, the latter for a path holding TEXT only.
    if (const char* point = std::getenv("CPVS_FAILPOINT")) {
      std::string p = point;
      if (const size_t colon = p.find(':'); colon != std::string::npos) {
        if (path.find(p.substr(colon + 1)) == std::string::npos) p.clear();
        p.resize(std::min(p.size(), colon));
      }
      if (p == "import-crash") raise(SIGSEGV);
      if (p == "import-escape") {
        // What a hostile file could try once it runs code in the importer: each refused.
        std::string tried;
        const int s = socket(AF_INET, SOCK_STREAM, 0);
        tried += s < 0 ? "socket refused" : "socket made";
        const std::string made = "/tmp/cpvs-import-escape-" + std::to_string(getpid());
        const int f = open(made.c_str(), O_WRONLY | O_CREAT, 0600);
        tried += f < 0 ? ", file refused" : ", file made";
        const pid_t child = fork();
        if (child == 0) _exit(0);
        tried += child < 0 ? ", fork refused" : ", fork made";
        char* const argv[] = {const_cast<char*>("/bin/true"), nullptr};
        execv(argv[0], argv);
        tried += ", exec refused";
        std::cerr << "escape: " << tried << "\n";
        return 4;
      }
      if (p == "import-hang")
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
      if (p == "import-hog") {
        // Address space is what the limit caps (RLIMIT_AS): reserving it is enough to
        // reach it, without the seconds a loaded machine spends zeroing the pages.
        std::vector<std::unique_ptr<char[]>> held;
        for (;;) held.emplace_back(new char[64 << 20]);
      }
    }
    SceneStats stats;
    const Scene scene = loadScene(path, &stats, ImportOptions{selfContained});
    const std::vector<uint8_t> mesh = encodeSceneMesh(scene, stats);
    std::cout.write(reinterpret_cast<const char*>(mesh.data()), std::streamsize(mesh.size()));
    std::cout.flush();
    // The process ends here: nothing to free (the scene, assimp's state), which would
    // only add to the import's time.
    std::_Exit(std::cout ? 0 : 3);
  } catch (const InputError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "out of memory\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 3;
  }
}

}  // namespace cpvs
