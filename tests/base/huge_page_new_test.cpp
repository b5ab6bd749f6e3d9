// The programs' operator new (core/src/base/huge_page_new.cpp): the whole 2 MiB pages
// inside a large block are advised for huge pages; a small block is malloc's as it was.
#include <gtest/gtest.h>
#include <sys/mman.h>

#include <cstdint>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cpvs/base/sanitizers.h"

// Under AddressSanitizer the sanitizer's operator new is kept: nothing to check there.
#if !defined(CPVS_ADDRESS_SANITIZER)

namespace {

constexpr uintptr_t kHugePage = uintptr_t(2) << 20;

// The first whole huge page inside a block.
const void* insideHugePage(const void* p) {
  return reinterpret_cast<const void*>((reinterpret_cast<uintptr_t>(p) + kHugePage - 1) & ~(kHugePage - 1));
}

// The VmFlags line of the mapping of /proc/self/smaps that holds `p`; empty if none.
std::string vmFlagsOf(const void* p) {
  const auto at = reinterpret_cast<uintptr_t>(p);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    uintptr_t begin = 0, end = 0;
    char dash = 0;
    std::istringstream range(line);
    if (range >> std::hex >> begin >> dash >> end && dash == '-' && line.find(' ') != std::string::npos &&
        line.find(':') > line.find(' ')) {
      inside = begin <= at && at < end;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return "";
}

// Whether this kernel takes the advice at all: one built without transparent huge pages
// refuses MADV_HUGEPAGE (EINVAL), and then there is nothing to see in smaps.
bool kernelTakesHugePageAdvice() {
  const size_t size = size_t(4) << 20;
  void* probe = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (probe == MAP_FAILED) return false;
  const bool taken = madvise(probe, size, MADV_HUGEPAGE) == 0;
  munmap(probe, size);
  return taken;
}

TEST(HugePageNew, LargeBlocksAreAdvisedForHugePages) {
  // Debian's kernels have them; a kernel without them is told nothing and gives 4 KiB pages.
  if (!kernelTakesHugePageAdvice()) GTEST_SKIP() << "this kernel has no transparent huge pages";
  std::vector<uint8_t> large(size_t(24) << 20, 1);
  const std::string flags = vmFlagsOf(insideHugePage(large.data()));
  ASSERT_FALSE(flags.empty()) << "no mapping holds the block in /proc/self/smaps";
  EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
  EXPECT_EQ(large[(size_t(24) << 20) - 1], 1);

  // Arrays and the nothrow form go through it too; all of them are freed by delete.
  std::unique_ptr<uint32_t[]> array(new uint32_t[size_t(2) << 20]);
  EXPECT_NE(vmFlagsOf(insideHugePage(array.get())).find(" hg"), std::string::npos);
  uint64_t* nothrow = new (std::nothrow) uint64_t[size_t(1) << 20];
  ASSERT_NE(nothrow, nullptr);
  EXPECT_NE(vmFlagsOf(insideHugePage(nothrow)).find(" hg"), std::string::npos);
  delete[] nothrow;

  // A small block is malloc's.
  auto small = std::make_unique<std::vector<uint8_t>>(4096, 2);
  EXPECT_EQ((*small)[4095], 2);
}

TEST(HugePageNew, AnImpossibleBlockThrowsBadAlloc) {
  volatile size_t beyondAnyMachine = SIZE_MAX - 4096, beyondThisOne = size_t(1) << 62;  // unknown to the compiler
  EXPECT_THROW((void)::operator new(beyondAnyMachine), std::bad_alloc);
  EXPECT_THROW((void)::operator new(beyondThisOne), std::bad_alloc);
}

}  // namespace

#endif
