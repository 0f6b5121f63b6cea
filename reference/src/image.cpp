// bloomref — image buffers (image.h: CacheAlignedAllocator).
#include "bloomref/image.h"

#include <new>

namespace bloomref::detail {

// Tried and not kept: 2 MiB alignment with madvise(MADV_HUGEPAGE) for large buffers. Passes after
// the first ran 10% faster, but faulting the huge pages in made the first blur pass ~3x slower
// (3840x2160, README: fast exact blur).
constexpr std::align_val_t kAlign{64};

void* allocate_pixels(std::size_t bytes) { return ::operator new(bytes, kAlign); }

void free_pixels(void* p, std::size_t) noexcept { ::operator delete(p, kAlign); }

}  // namespace bloomref::detail
