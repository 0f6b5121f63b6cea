#include "bloomref/engine/page_ledger.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <utility>

#include "bloomref/image.h"
#include "bloomref/parallel.h"

namespace bloomref::detail {

PageLedger::PageLedger(const void* base, std::size_t bytes) {
  static const std::uintptr_t page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
  const auto begin = reinterpret_cast<std::uintptr_t>(base);
  base_ = begin;
  shift_ = __builtin_ctzl(page);  // a power of two
  first_ = begin / page * page;
  end_ = (begin + bytes + page - 1) / page * page;
  done_.assign((end_ - first_) / page, 0);
}

PageLedger& PageLedger::operator=(PageLedger&& o) noexcept {
  if (this == &o) return *this;
  base_ = std::exchange(o.base_, 0);
  first_ = std::exchange(o.first_, 0);
  end_ = std::exchange(o.end_, 0);
  shift_ = o.shift_;
  done_ = std::exchange(o.done_, {});
  fresh_ = std::exchange(o.fresh_, {});
  populated_ = std::exchange(o.populated_, 0);
  visits_ = std::exchange(o.visits_, {});
  return *this;
}

bool PageLedger::marked(const void* p) const {
  return covers(p) && done_[(reinterpret_cast<std::uintptr_t>(p) - first_) >> shift_];
}

bool PageLedger::first_visit(const std::shared_ptr<const void>& family, int variant,
                             std::size_t i, std::size_t n) {
  auto it = std::find_if(visits_.begin(), visits_.end(), [&](const Visits& v) {
    return v.family == family && v.variant == variant;
  });
  if (it == visits_.end()) it = visits_.insert(visits_.end(), {family, variant, {}});
  if (it->seen.size() != n) it->seen.assign(n, 0);
  if (i >= n || it->seen[i]) return false;
  it->seen[i] = 1;
  return true;
}

void PageLedger::populate(int threads) {
#ifdef MADV_POPULATE_WRITE
  const std::uintptr_t page = std::uintptr_t(1) << shift_;
  if (fresh_.empty()) return;
  std::sort(fresh_.begin(), fresh_.end());
  // Runs of consecutive pages, one call each; the threads share the pages out (parallel_rows).
  const int n = static_cast<int>(fresh_.size());
  std::atomic<std::size_t> accepted{0};
  parallel_rows(n, std::min(resolve_threads(threads), 1 + n / 64), [&](int i0, int i1) {
    for (int i = i0; i < i1;) {
      int j = i + 1;
      while (j < i1 && fresh_[std::size_t(j)] == fresh_[std::size_t(j) - 1] + 1) ++j;
      if (::madvise(reinterpret_cast<void*>(first_ + fresh_[std::size_t(i)] * page),
                    std::size_t(j - i) * page, MADV_POPULATE_WRITE) == 0)
        accepted += std::size_t(j - i);
      i = j;
    }
  });
  populated_ += accepted;
#else
  (void)threads;
#endif
  fresh_.clear();
}

}  // namespace bloomref::detail
