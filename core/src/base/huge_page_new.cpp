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
// Linked into the executables only (cpvs, cpvs-server, cpvs-worker, cpvs-import, the tests and
// benchmarks), never into the runtime library an engine links. Only the one replaceable
// `operator new(std::size_t)` is replaced: libstdc++'s other forms call it, and every
// `operator delete` frees with free(). A block is malloc's, so its bytes are laid out as
// before (no alignment of our own, which fragmented malloc's heap).
// Under AddressSanitizer the sanitizer's own operator new is kept.
#include "cpvs/base/sanitizers.h"

#if !defined(CPVS_ADDRESS_SANITIZER)

#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace {

constexpr std::size_t kHugePage = std::size_t(2) << 20;
// Blocks from here on have at least one whole huge page inside.
constexpr std::size_t kLargeBlock = std::size_t(4) << 20;

}  // namespace

void* operator new(std::size_t size) {
  if (size >= kLargeBlock) {
    if (void* p = std::malloc(size)) {
      // The whole 2 MiB pages inside the block: only they can be huge, and nothing but
      // this block lies in them.
      const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + kHugePage - 1) & ~uintptr_t(kHugePage - 1);
      const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + size) & ~uintptr_t(kHugePage - 1);
      if (end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);  // advice only
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
