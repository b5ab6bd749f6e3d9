// The programs' operator new: a large block (a DAG level, a depth map, a file's bytes)
// is laid on 2 MiB pages where the kernel has them, a small one is malloc's.
//
// A bake allocates and fills hundreds of megabytes in blocks of tens of megabytes, a
// level or a tile at a time. On 4 KiB pages each block costs a page fault per 4 KiB on
// first touch, and under a hypervisor a fault is dear: a 64K bake through the tile cache
// spent a third of its time in faults and the kernel's zeroing of pages. Transparent huge
// pages on the blocks take 512 times fewer faults. Kernels that give huge pages only where
// asked (transparent_hugepage "madvise", Debian's default) are asked here, block by block;
// where they give none ("never") the advice is ignored and nothing else changes.
//
// Linked into the executables only (cpvs, cpvs-server, cpvs-worker, the tests and
// benchmarks), never into the runtime library an engine links. Only the one replaceable
// `operator new(std::size_t)` is replaced: libstdc++'s other forms call it, and every
// `operator delete` frees with free(), which takes what aligned_alloc and malloc give.
// Under AddressSanitizer the sanitizer's own operator new is kept.
#if !defined(__SANITIZE_ADDRESS__)

#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace {

constexpr std::size_t kHugePage = std::size_t(2) << 20;
// Below this a block's rounding to whole huge pages would waste more than it saves.
constexpr std::size_t kLargeBlock = std::size_t(4) << 20;

}  // namespace

void* operator new(std::size_t size) {
  if (size >= kLargeBlock && size <= SIZE_MAX - kHugePage) {
    const std::size_t rounded = (size + kHugePage - 1) & ~(kHugePage - 1);
    if (void* p = std::aligned_alloc(kHugePage, rounded)) {
      (void)madvise(p, rounded, MADV_HUGEPAGE);  // advice only: refused, the pages are small
      return p;
    }
  }
  for (;;) {
    if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
    const std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

#endif
