// bloomref — image buffers (image.h: CacheAlignedAllocator).
#include "bloomref/image.h"

#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace bloomref::detail {
namespace {

constexpr std::size_t kHugePage = std::size_t(2) << 20;
constexpr std::size_t kHugeFrom = std::size_t(1) << 62;  // smaller buffers: 64-byte alignment

std::size_t alignment_for(std::size_t bytes) { return bytes >= kHugeFrom ? kHugePage : 64; }

}  // namespace

void* allocate_pixels(std::size_t bytes) {
  const std::size_t align = alignment_for(bytes);
  void* p = ::operator new(bytes, std::align_val_t(align));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  // Advice only (where transparent huge pages are off, the buffer keeps small pages); the last
  // partial huge page is left out, it may be shared with another allocation.
  if (align == kHugePage) madvise(p, bytes / kHugePage * kHugePage, MADV_HUGEPAGE);
#endif
  return p;
}

void free_pixels(void* p, std::size_t bytes) noexcept {
  ::operator delete(p, std::align_val_t(alignment_for(bytes)));
}

}  // namespace bloomref::detail
