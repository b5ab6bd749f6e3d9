// LD_PRELOAD shim for the wall-clock tests: the process' wall clock (CLOCK_REALTIME, as
// std::chrono::system_clock, time() and gettimeofday read it) runs the number of seconds
// ahead (or behind, when negative) that the file named by CPVS_CLOCK_OFFSET_FILE holds,
// as after an NTP step or an operator setting the date; the steady clock does not move.
// The file is read again at most every 50 ms of the steady clock.
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

typedef int (*clock_gettime_fn)(clockid_t, struct timespec*);

static clock_gettime_fn real_clock_gettime(void) {
  static _Atomic(clock_gettime_fn) real = NULL;
  clock_gettime_fn f = atomic_load(&real);
  if (f == NULL) {
    f = (clock_gettime_fn)dlsym(RTLD_NEXT, "clock_gettime");
    atomic_store(&real, f);
  }
  return f;
}

static long long offset_ns(void) {
  static _Atomic long long offset = 0, read_at = -1000000000LL;
  struct timespec now;
  real_clock_gettime()(CLOCK_MONOTONIC, &now);
  const long long t = now.tv_sec * 1000000000LL + now.tv_nsec;
  if (t - atomic_load(&read_at) > 50000000LL) {
    atomic_store(&read_at, t);
    const char* path = getenv("CPVS_CLOCK_OFFSET_FILE");
    long long value = 0;
    if (path != NULL) {
      const int fd = open(path, O_RDONLY | O_CLOEXEC);
      if (fd >= 0) {
        char text[64] = {0};
        const ssize_t n = read(fd, text, sizeof text - 1);
        close(fd);
        if (n > 0) value = (long long)(atof(text) * 1e9);
      }
    }
    atomic_store(&offset, value);
  }
  return atomic_load(&offset);
}

static void shift(struct timespec* ts) {
  const long long ns = ts->tv_sec * 1000000000LL + ts->tv_nsec + offset_ns();
  ts->tv_sec = ns / 1000000000LL;
  ts->tv_nsec = ns % 1000000000LL;
}

int clock_gettime(clockid_t id, struct timespec* ts) {
  const int r = real_clock_gettime()(id, ts);
  if (r == 0 && (id == CLOCK_REALTIME || id == CLOCK_REALTIME_COARSE)) shift(ts);
  return r;
}

int gettimeofday(struct timeval* restrict tv, void* restrict tz) {
  (void)tz;
  struct timespec ts;
  const int r = clock_gettime(CLOCK_REALTIME, &ts);
  if (r == 0 && tv != NULL) {
    tv->tv_sec = ts.tv_sec;
    tv->tv_usec = ts.tv_nsec / 1000;
  }
  return r;
}

time_t time(time_t* out) {
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  if (out != NULL) *out = ts.tv_sec;
  return ts.tv_sec;
}
