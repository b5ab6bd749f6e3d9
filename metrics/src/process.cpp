#include "cpvs/metrics/process.h"

#include <sys/resource.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cpvs/metrics/families.h"

namespace cpvs::metrics {

namespace {

// The fields of /proc/self/stat after the command name (which may hold spaces), from
// field 3 (state) on: index i here is field i + 3 of proc(5).
std::vector<std::string> statFields() {
  std::ifstream in("/proc/self/stat");
  std::string line;
  std::getline(in, line);
  std::vector<std::string> fields;
  const size_t close = line.rfind(')');
  if (close == std::string::npos) return fields;
  std::istringstream rest(line.substr(close + 1));
  for (std::string f; rest >> f;) fields.push_back(f);
  return fields;
}

double bootTimeSeconds() {
  std::ifstream in("/proc/stat");
  for (std::string key; in >> key;) {
    if (key == "btime") {
      double t = 0;
      in >> t;
      return t;
    }
    in.ignore(1 << 20, '\n');
  }
  return 0;
}

}  // namespace

ProcessMetrics::ProcessMetrics(prometheus::Registry& registry)
    : resident_(gauge(registry, "process_resident_memory_bytes", "Resident memory size in bytes.")),
      virtual_(gauge(registry, "process_virtual_memory_bytes", "Virtual memory size in bytes.")),
      openFds_(gauge(registry, "process_open_fds", "Number of open file descriptors.")),
      maxFds_(gauge(registry, "process_max_fds", "Maximum number of open file descriptors.")),
      threads_(gauge(registry, "process_threads", "Number of OS threads in the process.")),
      startTime_(
          gauge(registry, "process_start_time_seconds", "Start time of the process since unix epoch in seconds.")),
      cpuSeconds_(counter(registry, "process_cpu_seconds_total", "Total user and system CPU time spent in seconds.")) {
  refresh();
}

void ProcessMetrics::refresh() {
  const std::vector<std::string> f = statFields();
  const double tick = double(sysconf(_SC_CLK_TCK));
  const double page = double(sysconf(_SC_PAGESIZE));
  // proc(5): utime 14, stime 15, num_threads 20, starttime 22, vsize 23, rss 24.
  if (f.size() > 21 && tick > 0) {
    const double cpu = (std::stod(f[11]) + std::stod(f[12])) / tick;
    if (cpu > cpuSecondsSeen_) cpuSeconds_.Increment(cpu - cpuSecondsSeen_);
    cpuSecondsSeen_ = std::max(cpuSecondsSeen_, cpu);
    threads_.Set(std::stod(f[17]));
    startTime_.Set(bootTimeSeconds() + std::stod(f[19]) / tick);
    virtual_.Set(std::stod(f[20]));
    resident_.Set(std::stod(f[21]) * page);
  }
  std::error_code ec;
  size_t fds = 0;
  for (auto it = std::filesystem::directory_iterator("/proc/self/fd", ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec))
    ++fds;
  openFds_.Set(double(fds));
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) == 0)
    maxFds_.Set(limit.rlim_cur == RLIM_INFINITY ? -1.0 : double(limit.rlim_cur));
}

}  // namespace cpvs::metrics
