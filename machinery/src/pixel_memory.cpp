// bloomref — the memory image buffers live in (pixel_memory.h).
#include "bloomref/pixel_memory.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <utility>

namespace bloomref {

// Not the default: 2 MiB alignment with madvise(MADV_HUGEPAGE) for large buffers. A command
// runs one image, and faulting huge pages in costs more than its later passes save; a process
// that keeps its buffers opts in (advise_huge_pages). docs/design.md, "Large buffers advised for
// huge pages in the Python process".
namespace {
constexpr std::align_val_t kAlign{64};
std::atomic<bool> huge_pages{false};
constexpr std::size_t kMinHugeAdvised = std::size_t(4) << 20;  // numpy's threshold

// The 2 MiB pages wholly inside [p, p + bytes), advised for transparent huge pages.
void advise_huge(void* p, std::size_t bytes) noexcept {
  constexpr std::uintptr_t huge = std::uintptr_t(2) << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = (begin + huge - 1) / huge * huge;
  const std::uintptr_t last = (begin + bytes) / huge * huge;
  if (first < last) ::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
}
}  // namespace

// Freed buffers of at least 16 MiB, up to PixelPolicy::keep_bytes in all, are kept for the next
// buffer of the same size: malloc maps blocks that large afresh and hands them back when freed,
// so every new image of a size seen before faulted its pages in again. docs/design.md, "Large
// image buffers are kept for the next image of their size".
namespace {
constexpr std::size_t kMinKept = std::size_t(16) << 20;
struct Kept {
  void* p = nullptr;
  std::size_t bytes = 0;
};
std::mutex kept_mutex;
std::array<Kept, 64> kept;  // PixelPolicy::kMostKept / kMinKept
std::atomic<std::size_t> keep_bytes{PixelPolicy{}.keep_bytes};
std::atomic<bool> prefault_new{false};
}  // namespace

void* allocate_pixels(std::size_t bytes) {
  if (bytes >= kMinKept) {
    const std::lock_guard<std::mutex> lock(kept_mutex);
    for (Kept& k : kept)
      if (k.p && k.bytes == bytes) return std::exchange(k.p, nullptr);
  }
  void* p = ::operator new(bytes, kAlign);
  if (bytes >= kMinHugeAdvised && huge_pages.load(std::memory_order_relaxed)) advise_huge(p, bytes);
  if (bytes >= kMinKept && prefault_new.load(std::memory_order_relaxed)) prefault(p, bytes);
  return p;
}

PixelPolicy pixel_policy() noexcept {
  return {keep_bytes.load(std::memory_order_relaxed), prefault_new.load(std::memory_order_relaxed)};
}

PixelPolicy set_pixel_policy(const PixelPolicy& policy) noexcept {
  const PixelPolicy old = pixel_policy();
  const std::size_t most = std::min(policy.keep_bytes, PixelPolicy::kMostKept);
  keep_bytes.store(most, std::memory_order_relaxed);
  prefault_new.store(policy.prefault_new, std::memory_order_relaxed);
  // What is kept beyond the new limit is handed back, the largest first.
  const std::lock_guard<std::mutex> lock(kept_mutex);
  std::size_t held = 0;
  for (const Kept& k : kept) held += k.p ? k.bytes : 0;
  while (held > most) {
    Kept* largest = nullptr;
    for (Kept& k : kept)
      if (k.p && (!largest || k.bytes > largest->bytes)) largest = &k;
    held -= largest->bytes;
    ::operator delete(std::exchange(largest->p, nullptr), kAlign);
  }
  return old;
}

void advise_huge_pages(bool on) noexcept { huge_pages.store(on, std::memory_order_relaxed); }

void free_pixels(void* p, std::size_t bytes) noexcept {
  const std::size_t most = keep_bytes.load(std::memory_order_relaxed);
  if (p && bytes >= kMinKept && bytes <= most) {
    const std::lock_guard<std::mutex> lock(kept_mutex);
    std::size_t held = 0;
    Kept* slot = nullptr;
    for (Kept& k : kept) {
      if (k.p) held += k.bytes;
      else if (!slot) slot = &k;
    }
    if (slot && held + bytes <= most) {
      *slot = {p, bytes};
      return;
    }
  }
  ::operator delete(p, kAlign);
}

// Cheaper than a fault per page on first touch (docs/design.md, "Nothing is written where
// nothing is"). Huge pages are not used: fast when the kernel has one free, far slower when it
// must compact memory first.
void prefault(void* p, std::size_t bytes) noexcept {
#ifdef MADV_POPULATE_WRITE
  static const std::uintptr_t page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = (begin + page - 1) / page * page, last = (begin + bytes) / page * page;
  if (first < last) ::madvise(reinterpret_cast<void*>(first), last - first, MADV_POPULATE_WRITE);
#else
  (void)p;
  (void)bytes;
#endif
}

void zero_lazily(void* p, std::size_t bytes) noexcept {
  if (bytes == 0) return;
  static const std::uintptr_t page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
  const auto begin = reinterpret_cast<std::uintptr_t>(p), end = begin + bytes;
  const std::uintptr_t first = (begin + page - 1) / page * page, last = end / page * page;
  const std::size_t pages = first < last ? (last - first) / page : 0;
  // Which pages are resident (mincore): those are written (a resident page costs a memset; given
  // back, it would cost a fault and the kernel's zeroing when written again, as a buffer
  // recycled by malloc is), the runs of the others given back with madvise. Where either call
  // refuses, memset.
  std::unique_ptr<unsigned char[]> resident(pages ? new (std::nothrow) unsigned char[pages] : nullptr);
  if (!resident || ::mincore(reinterpret_cast<void*>(first), last - first, resident.get()) != 0) {
    std::memset(p, 0, bytes);
    return;
  }
  std::memset(p, 0, first - begin);
  std::memset(reinterpret_cast<void*>(last), 0, end - last);
  for (std::size_t i = 0; i < pages;) {
    std::size_t j = i + 1;
    const bool in_core = resident[i] & 1;
    while (j < pages && bool(resident[j] & 1) == in_core) ++j;
    void* run = reinterpret_cast<void*>(first + i * page);
    const std::size_t run_bytes = (j - i) * page;
    if (in_core || ::madvise(run, run_bytes, MADV_DONTNEED) != 0) std::memset(run, 0, run_bytes);
    i = j;
  }
}

}  // namespace bloomref
