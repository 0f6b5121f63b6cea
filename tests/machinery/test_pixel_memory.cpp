// The memory image buffers live in (pixel_memory.h, image.h): prefault, kept buffers, huge-page
// advice, lazy zeroing, cache-line alignment.
#include <sys/mman.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/pixel_memory.h"

using namespace bloomref;

TEST_CASE("prefault makes pages resident and leaves every value as it was", "[stages]") {
  // 64 pages of a fresh anonymous mapping, one written with a pattern, the range starting and
  // ending inside a page: after prefault the pages wholly inside the range are resident (mincore;
  // checked where the kernel has MADV_POPULATE_WRITE, without it the call does nothing), and
  // every byte still reads as before: the pattern or zero.
  const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE)), npages = 64;
  void* m = ::mmap(nullptr, npages * pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1,
                   0);
  REQUIRE(m != MAP_FAILED);
  auto* bytes = static_cast<unsigned char*>(m);
  std::memset(bytes + 10 * pg, 0xA5, pg);
  bloomref::prefault(bytes + 100, npages * pg - 200);
  std::vector<unsigned char> in_core(npages);
  REQUIRE(::mincore(m, npages * pg, in_core.data()) == 0);
  std::size_t resident_inside = 0;
  for (std::size_t i = 1; i + 1 < npages; ++i) resident_inside += in_core[i] & 1;
#ifdef MADV_POPULATE_WRITE
  // Whether this kernel has the call: asked of a page of its own.
  void* probe = ::mmap(nullptr, pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  REQUIRE(probe != MAP_FAILED);
  const bool kernel_has_it = ::madvise(probe, pg, MADV_POPULATE_WRITE) == 0;
  ::munmap(probe, pg);
  if (kernel_has_it) CHECK(resident_inside == npages - 2);
#endif
  std::size_t as_before = 0;
  for (std::size_t i = 0; i < npages * pg; ++i)
    as_before += bytes[i] == ((i / pg == 10) ? 0xA5 : 0);
  CHECK(as_before == npages * pg);
  ::munmap(m, npages * pg);
}

TEST_CASE("a freed large image buffer serves the next image of its size, with that image's values",
          "[stages]") {
  // A 2048x1024 RGBA float image (32 MiB) written whole, then freed: the next image of that size
  // gets the same memory, still resident (mincore: a buffer handed back to the kernel and mapped
  // afresh would have no page resident before it is written); freed again, it serves
  // Image::zeroed, which reads all zero over that dirty memory.
  const int w = 2048, h = 1024;
  const std::size_t bytes = std::size_t(w) * h * bloomref::kChannels * sizeof(float);
  const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE));
  const void* first = nullptr;
  {
    Image a = Image::uninitialised(w, h);
    std::fill(a.data(), a.data() + a.pixel_count() * bloomref::kChannels, -3.25f);
    first = a.data();
  }
  Image b = Image::uninitialised(w, h);
  CHECK(static_cast<const void*>(b.data()) == first);
  {
    const auto begin = (reinterpret_cast<std::uintptr_t>(b.data()) + pg - 1) / pg * pg;
    const std::size_t n = (reinterpret_cast<std::uintptr_t>(b.data()) + bytes - begin) / pg;
    std::vector<unsigned char> in_core(n);
    REQUIRE(::mincore(reinterpret_cast<void*>(begin), n * pg, in_core.data()) == 0);
    std::size_t resident = 0;
    for (unsigned char v : in_core) resident += v & 1;
    CHECK(resident == n);
  }
  b = Image();
  const Image z = Image::zeroed(w, h);
  CHECK(static_cast<const void*>(z.data()) == first);
  CHECK(std::count(z.data(), z.data() + z.pixel_count() * bloomref::kChannels, 0.0f) ==
        std::ptrdiff_t(z.pixel_count() * bloomref::kChannels));
}

namespace {
// Whether every mapping of this process that overlaps [begin, end) is advised for transparent
// huge pages ("hg" among its VmFlags in /proc/self/smaps, proc(5)); false where none overlaps.
bool huge_advised(std::uintptr_t begin, std::uintptr_t end) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool overlaps = false, any = false, all = true;
  while (std::getline(smaps, line)) {
    unsigned long lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (line.rfind("VmFlags:", 0) == 0) {
      if (overlaps) {
        any = true;
        all = all && (line + " ").find(" hg ") != std::string::npos;
      }
    } else if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      overlaps = lo < end && begin < hi;
    }
  }
  return any && all;
}
}  // namespace

TEST_CASE("advise_huge_pages: new buffers of 4 MiB or more advised for huge pages, whole 2 MiB "
          "pages",
          "[stages]") {
  // An image of 6 MiB (under the 16 MiB of kept buffers: always a new one), before and after
  // the call: only after it are its whole 2 MiB pages advised (the kernel's own record of the
  // mappings, not the allocator's); one just under 4 MiB never is.
  if (::access("/sys/kernel/mm/transparent_hugepage", F_OK) != 0) {
    WARN("this kernel has no transparent huge pages: nothing to check");
    return;
  }
  constexpr std::uintptr_t huge = std::uintptr_t(2) << 20;
  const auto inside = [&](const Image& img) {
    const auto b = reinterpret_cast<std::uintptr_t>(img.data());
    const std::uintptr_t first = (b + huge - 1) / huge * huge;
    const std::uintptr_t last = (b + img.pixel_count() * sizeof(float) * 4) / huge * huge;
    return std::make_pair(first, last);
  };
  const Image before = Image::uninitialised(1024, 384);  // 6 MiB
  const auto [b0, b1] = inside(before);
  REQUIRE(b1 - b0 >= huge);
  CHECK_FALSE(huge_advised(b0, b1));
  bloomref::advise_huge_pages(true);
  const Image after = Image::uninitialised(1024, 384);
  const Image small = Image::uninitialised(1024, 255);  // 16 KiB under 4 MiB
  bloomref::advise_huge_pages(false);
  const auto [a0, a1] = inside(after);
  REQUIRE(a1 - a0 >= huge);
  CHECK(huge_advised(a0, a1));
  const auto [s0, s1] = inside(small);
  if (s0 < s1) CHECK_FALSE(huge_advised(s0, s1));
  // Off again: the next buffer is not advised.
  const Image later = Image::uninitialised(1024, 384);
  const auto [l0, l1] = inside(later);
  CHECK_FALSE(huge_advised(l0, l1));
}

TEST_CASE("zero_lazily and Image::zeroed give zero bytes over dirty memory, any alignment",
          "[stages]") {
  // Dirty heap memory (written with a pattern) at offsets that are not page-aligned, sizes below,
  // at and across page boundaries: every byte in the range becomes 0, the bytes around it keep
  // the pattern.
  const std::size_t page = 4096;
  std::vector<unsigned char> buf(8 * page + 64);
  for (std::size_t off : {std::size_t(0), std::size_t(1), std::size_t(63), page - 3, page}) {
    for (std::size_t n : {std::size_t(0), std::size_t(5), page, page + 7, 3 * page + 100,
                          6 * page}) {
      std::fill(buf.begin(), buf.end(), 0xA5);
      bloomref::zero_lazily(buf.data() + off, n);
      std::size_t zero = 0, kept = 0;
      for (std::size_t i = 0; i < buf.size(); ++i) {
        const bool inside = i >= off && i < off + n;
        zero += inside && buf[i] == 0;
        kept += !inside && buf[i] == 0xA5;
      }
      INFO("offset " << off << " bytes " << n);
      CHECK(zero == n);
      CHECK(kept == buf.size() - n);
    }
  }
  // Pages never written stay unwritten (the point of "lazily"): 64 fresh pages of an anonymous
  // mapping with one written in the middle (resident, dirty); after zero_lazily only that one is
  // resident (mincore, before anything reads the others), and every byte reads as zero.
  {
    const std::size_t pg = std::size_t(::sysconf(_SC_PAGESIZE)), npages = 64;
    void* m = ::mmap(nullptr, npages * pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS,
                     -1, 0);
    REQUIRE(m != MAP_FAILED);
    auto* bytes = static_cast<unsigned char*>(m);
    std::memset(bytes + 10 * pg, 0xA5, pg);
    bloomref::zero_lazily(bytes, npages * pg);
    std::vector<unsigned char> in_core(npages);
    REQUIRE(::mincore(m, npages * pg, in_core.data()) == 0);
    std::size_t resident = 0;
    for (unsigned char v : in_core) resident += v & 1;
    CHECK(resident <= 1);
    CHECK(std::count(bytes, bytes + npages * pg, 0) == std::ptrdiff_t(npages * pg));
    ::munmap(m, npages * pg);
  }
  for (int round = 0; round < 3; ++round) {
    {
      Image dirty(1024, 1024, -7.0f);  // 16 MiB: leaves dirty memory for the next allocation
    }
    const Image z = Image::zeroed(1024, 1024);
    CHECK(reinterpret_cast<std::uintptr_t>(z.data()) % 64 == 0);
    std::size_t nonzero = 0;
    for (float v : z.values()) nonzero += std::signbit(v) || v != 0.0f;
    CHECK(nonzero == 0);
  }
}

TEST_CASE("image buffers start on a cache line, the fill constructor fills, copies keep values",
          "[stages]") {
  for (auto [w, h] : {std::pair{1, 1}, {3, 7}, {1920, 1080}}) {
    Image img(w, h, 0.25f);
    CHECK(reinterpret_cast<std::uintptr_t>(img.data()) % 64 == 0);
    CHECK(std::count(img.values().begin(), img.values().end(), 0.25f) ==
          std::ptrdiff_t(img.values().size()));
    Image u = Image::uninitialised(w, h);
    CHECK(reinterpret_cast<std::uintptr_t>(u.data()) % 64 == 0);
    CHECK(u.values().size() == std::size_t(w) * h * kChannels);
    const Image copy = img;  // the allocator's copy: a new aligned buffer, same values
    CHECK(copy.data() != img.data());
    CHECK(reinterpret_cast<std::uintptr_t>(copy.data()) % 64 == 0);
    CHECK(copy.values() == img.values());
    ImageF64 d(w, h, -1.5);
    CHECK(reinterpret_cast<std::uintptr_t>(d.data()) % 64 == 0);
    CHECK(d.values().back() == -1.5);
  }
}
