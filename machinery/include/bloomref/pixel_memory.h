// bloomref — the memory image buffers live in: allocation aligned to a cache line, freed large
// buffers kept for the next one of their size, and the page-level calls the stages use on a
// buffer they are about to write (Linux madvise; elsewhere plain memory operations).
#pragma once

#include <cstddef>

namespace bloomref {

void* allocate_pixels(std::size_t bytes);
void free_pixels(void* p, std::size_t bytes) noexcept;
/// Faults in the whole pages of [p, p + bytes) in one call (madvise MADV_POPULATE_WRITE, Linux
/// 5.14+; elsewhere nothing), for a buffer about to be written whole: cheaper than a fault per
/// page on first touch (docs/design.md has the figures). The values are left as they are.
void prefault(void* p, std::size_t bytes) noexcept;
/// Sets `bytes` at p to zero without writing the whole pages inside that are not resident: those
/// are handed back to the kernel (madvise MADV_DONTNEED: private anonymous memory then reads as
/// zero, and a page is only materialised when written); resident pages and the partial pages at
/// the ends are written. Falls back to memset where mincore or madvise refuses.
void zero_lazily(void* p, std::size_t bytes) noexcept;
/// How the process treats buffers of at least 16 MiB (process-wide; set_pixel_policy).
struct PixelPolicy {
  static constexpr std::size_t kMostKept = std::size_t(1) << 30;
  /// Freed buffers kept for the next buffer of their size, in bytes in all (at most kMostKept):
  /// a buffer taken again costs no page faults.
  std::size_t keep_bytes = std::size_t(96) << 20;
  /// New buffers faulted in whole when allocated (prefault): one call in place of a fault per
  /// page, for a process whose buffers are written whole (check's oracles, bounds, decoded stages).
  bool prefault_new = false;
};
PixelPolicy pixel_policy() noexcept;
/// Sets the policy, handing back kept buffers beyond its keep_bytes; returns the one before.
PixelPolicy set_pixel_policy(const PixelPolicy& policy) noexcept;

/// A policy for the lifetime of this object; the one before restored after it.
class PixelPolicyScope {
 public:
  explicit PixelPolicyScope(const PixelPolicy& policy) : before_(set_pixel_policy(policy)) {}
  ~PixelPolicyScope() { set_pixel_policy(before_); }
  PixelPolicyScope(const PixelPolicyScope&) = delete;
  PixelPolicyScope& operator=(const PixelPolicyScope&) = delete;

 private:
  PixelPolicy before_;
};

/// From this call on (with `on`), every new buffer of at least 4 MiB has its whole 2 MiB pages
/// advised for transparent huge pages (madvise MADV_HUGEPAGE, before anything is written), as
/// numpy advises its own arrays of that size. For a process that runs many images of one size
/// and keeps their buffers (the Python module): fewer TLB misses on every later pass, at the
/// cost of a slower first touch (docs/design.md has the figures). Off by default.
void advise_huge_pages(bool on) noexcept;

}  // namespace bloomref
