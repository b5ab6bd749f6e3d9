// LD_PRELOAD shim for the power-loss tests: it journals what a process makes durable under
// one folder, so that after the process is killed the test can drop every write a power
// cut would have lost (powercut.h replays the journal). With CPVS_POWERCUT_DIR naming the
// folder and CPVS_POWERCUT_LOG the journal, it appends one line per event, each with one
// write() on an O_APPEND descriptor, so a SIGKILL never leaves half a line:
//   C INODE PATH    a file created (it did not exist before the open)
//   T INODE         an existing file truncated by open(O_TRUNC)
//   M PATH          a folder created
//   S INODE SIZE    a file synced (fsync or fdatasync) at this size
//   D PATH          a folder synced (under the folder, or the one holding it)
//   R INODE FROM TO a rename
// Nothing else changes: every call goes on to the C library.
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#define REAL(name, type) \
  static type real = NULL; \
  if (real == NULL) real = (type)dlsym(RTLD_NEXT, name)

static const char* folder(void) { return getenv("CPVS_POWERCUT_DIR"); }

/// Whether an absolute or relative path lies under the journaled folder.
static int under(const char* path) {
  const char* dir = folder();
  if (dir == NULL || path == NULL) return 0;
  size_t n = strlen(dir);
  while (n > 1 && dir[n - 1] == '/') --n;  // "/data/" is "/data"
  char resolved[4096];
  if (path[0] != '/') {
    if (getcwd(resolved, sizeof resolved - 1) == NULL) return 0;
    const size_t n = strlen(resolved);
    snprintf(resolved + n, sizeof resolved - n, "/%s", path);
    path = resolved;
  }
  return strncmp(path, dir, n) == 0 && (path[n] == '/' || path[n] == 0);
}

/// Whether `path` is the folder that holds the journaled one (whose sync makes it durable).
static int holdsFolder(const char* path) {
  const char* dir = folder();
  if (dir == NULL) return 0;
  const char* slash = strrchr(dir, '/');
  if (slash == NULL) return 0;
  const size_t n = slash == dir ? 1 : (size_t)(slash - dir);
  return strlen(path) == n && strncmp(path, dir, n) == 0;
}

static void absolute(const char* path, char* out, size_t size) {
  if (path[0] == '/' || getcwd(out, size - 1) == NULL) {
    snprintf(out, size, "%s", path);
    return;
  }
  const size_t n = strlen(out);
  snprintf(out + n, size - n, "/%s", path);
}

static void journal(const char* line) {
  static int fd = -1;
  if (fd < 0) {
    const char* log = getenv("CPVS_POWERCUT_LOG");
    if (log == NULL) return;
    typedef int (*plain_open)(const char*, int, ...);
    plain_open real = (plain_open)dlsym(RTLD_NEXT, "open");  // the journal itself is not journaled
    fd = real(log, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) return;
  }
  ssize_t ignored = write(fd, line, strlen(line));
  (void)ignored;
}

static int fdPath(int fd, char* out, size_t size) {
  char link[64];
  snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  const ssize_t n = readlink(link, out, size - 1);
  if (n <= 0) return 0;
  out[n] = 0;
  return 1;
}

/// Whether open's flags say a mode follows (O_TMPFILE holds O_DIRECTORY's bit).
static int takesMode(int flags) { return (flags & O_CREAT) || (flags & O_TMPFILE) == O_TMPFILE; }

typedef int (*openat_fn)(int, const char*, int, ...);

/// Journals a successful open of `path` that may have created or truncated it.
static void opened(int fd, const char* path, int flags, int existed) {
  if (fd < 0 || !(flags & (O_CREAT | O_TRUNC)) || !under(path)) return;
  struct stat st;
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return;
  char line[4400], full[4096];
  absolute(path, full, sizeof full);
  if (!existed)
    snprintf(line, sizeof line, "C %llu %s\n", (unsigned long long)st.st_ino, full);
  else if (flags & O_TRUNC)
    snprintf(line, sizeof line, "T %llu\n", (unsigned long long)st.st_ino);
  else
    return;
  journal(line);
}

static int existsNow(const char* path) {
  struct stat st;
  return stat(path, &st) == 0;
}

/// Every open goes through here with its mode read: `dirfd` is AT_FDCWD for open and
/// open64. Paths relative to another descriptor than the working folder are not journaled.
static int journaledOpen(openat_fn real, int dirfd, const char* path, int flags, mode_t mode) {
  const int watched = (flags & (O_CREAT | O_TRUNC)) && (dirfd == AT_FDCWD || path[0] == '/') && under(path);
  const int existed = watched ? existsNow(path) : 1;
  const int fd = real(dirfd, path, flags, mode);
  if (watched) opened(fd, path, flags, existed);
  return fd;
}

#define MODE_ARG(mode)              \
  mode_t mode = 0;                  \
  if (takesMode(flags)) {           \
    va_list ap;                     \
    va_start(ap, flags);            \
    mode = (mode_t)va_arg(ap, int); \
    va_end(ap);                     \
  }

int open(const char* path, int flags, ...) {
  MODE_ARG(mode);
  REAL("openat", openat_fn);
  return journaledOpen(real, AT_FDCWD, path, flags, mode);
}

int open64(const char* path, int flags, ...) {
  MODE_ARG(mode);
  REAL("openat64", openat_fn);
  return journaledOpen(real, AT_FDCWD, path, flags, mode);
}

int openat(int dirfd, const char* path, int flags, ...) {
  MODE_ARG(mode);
  REAL("openat", openat_fn);
  return journaledOpen(real, dirfd, path, flags, mode);
}

int openat64(int dirfd, const char* path, int flags, ...) {
  MODE_ARG(mode);
  REAL("openat64", openat_fn);
  return journaledOpen(real, dirfd, path, flags, mode);
}

int creat(const char* path, mode_t mode) { return open(path, O_WRONLY | O_CREAT | O_TRUNC, mode); }

typedef int (*mkdir_fn)(const char*, mode_t);

int mkdir(const char* path, mode_t mode) {
  REAL("mkdir", mkdir_fn);
  const int r = real(path, mode);
  if (r == 0 && under(path)) {
    char line[4200], full[4096];
    absolute(path, full, sizeof full);
    snprintf(line, sizeof line, "M %s\n", full);
    journal(line);
  }
  return r;
}

static void synced(int fd) {
  char path[4096];
  if (!fdPath(fd, path, sizeof path) || !(under(path) || holdsFolder(path))) return;
  struct stat st;
  if (fstat(fd, &st) != 0) return;
  char line[4200];
  if (S_ISDIR(st.st_mode))
    snprintf(line, sizeof line, "D %s\n", path);
  else if (S_ISREG(st.st_mode))
    snprintf(line, sizeof line, "S %llu %lld\n", (unsigned long long)st.st_ino, (long long)st.st_size);
  else
    return;
  journal(line);
}

typedef int (*sync_fn)(int);

int fsync(int fd) {
  REAL("fsync", sync_fn);
  const int r = real(fd);
  if (r == 0) synced(fd);
  return r;
}

int fdatasync(int fd) {
  REAL("fdatasync", sync_fn);
  const int r = real(fd);
  if (r == 0) synced(fd);
  return r;
}

static void renamed(const char* from, const char* to) {
  if (!under(to) && !under(from)) return;
  struct stat st;
  if (stat(to, &st) != 0) return;
  char line[8400], a[4096], b[4096];
  absolute(from, a, sizeof a);
  absolute(to, b, sizeof b);
  snprintf(line, sizeof line, "R %llu %s %s\n", (unsigned long long)st.st_ino, a, b);
  journal(line);
}

typedef int (*rename_fn)(const char*, const char*);
typedef int (*renameat_fn)(int, const char*, int, const char*);
typedef int (*renameat2_fn)(int, const char*, int, const char*, unsigned int);

int rename(const char* from, const char* to) {
  REAL("rename", rename_fn);
  const int r = real(from, to);
  if (r == 0) renamed(from, to);
  return r;
}

int renameat(int fromDir, const char* from, int toDir, const char* to) {
  REAL("renameat", renameat_fn);
  const int r = real(fromDir, from, toDir, to);
  if (r == 0 && (fromDir == AT_FDCWD || from[0] == '/') && (toDir == AT_FDCWD || to[0] == '/')) renamed(from, to);
  return r;
}

int renameat2(int fromDir, const char* from, int toDir, const char* to, unsigned int flags) {
  REAL("renameat2", renameat2_fn);
  const int r = real(fromDir, from, toDir, to, flags);
  if (r == 0 && (fromDir == AT_FDCWD || from[0] == '/') && (toDir == AT_FDCWD || to[0] == '/')) renamed(from, to);
  return r;
}
