// bloomref engine — page ledgers: which pages of a lazily zeroed buffer the adaptive plan's
// sparse passes have made writable (image.h: zero_lazily).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace bloomref::detail {

/// The pages of one buffer that a sparse computation has made writable so far. A zeroed buffer's
/// pages exist only where written (zero_lazily); reading one that was never written maps the
/// kernel's shared zero page, and writing it afterwards is a copy-on-write fault that flushes
/// every CPU's TLB (a cross-CPU interrupt, dear in a virtual machine). A computation that knows
/// which parts it will read and write marks them here first; populate() then faults the pages
/// marked for the first time in writable (madvise MADV_POPULATE_WRITE, Linux 5.14+; elsewhere
/// nothing), shared out between threads, before anything reads them. A default ledger covers
/// no page.
class PageLedger {
 public:
  PageLedger() = default;
  PageLedger(const void* base, std::size_t bytes);
  /// A moved-from ledger covers no page (it would otherwise keep its range with no page marks,
  /// and a buffer sharing a page with the old one could find it).
  PageLedger(PageLedger&& o) noexcept { *this = std::move(o); }
  PageLedger& operator=(PageLedger&& o) noexcept;
  PageLedger(const PageLedger&) = delete;
  PageLedger& operator=(const PageLedger&) = delete;
  /// Whether this is the ledger of the buffer that starts at `base`: covers() is not enough, two
  /// buffers can share a page (small images come from the heap, one after another).
  bool of(const void* base) const {
    return base_ != 0 && reinterpret_cast<std::uintptr_t>(base) == base_;
  }
  /// Marks the pages of [p, p + bytes); ranges outside the ledger's buffer are ignored. Inline:
  /// a sparse pass marks each row of each tile it visits for the first time.
  void mark(const void* p, std::size_t bytes) {
    const auto begin = reinterpret_cast<std::uintptr_t>(p);
    if (bytes == 0 || begin < first_ || begin + bytes > end_) return;
    for (std::size_t i = (begin - first_) >> shift_, last = (begin + bytes - 1 - first_) >> shift_;
         i <= last; ++i)
      if (!done_[i]) {
        done_[i] = 1;
        fresh_.push_back(i);
      }
  }
  /// Faults in writable the pages marked since the last call that no earlier call did.
  void populate(int threads);
  /// Pages populate has faulted in so far (those of calls the kernel accepted).
  std::size_t populated() const { return populated_; }
  /// Whether the page holding byte p was marked.
  bool marked(const void* p) const;
  /// Whether byte p lies in a page of the ledger's buffer.
  bool covers(const void* p) const {
    const auto at = reinterpret_cast<std::uintptr_t>(p);
    return at >= first_ && at < end_;
  }
  /// Whether element i of a family of n regions is visited here for the first time. A family is
  /// an object (held here, so its address names it as long as the ledger lives) and a variant
  /// (a pass's tables, and whether its tiles are read or written, small or not). A caller that
  /// marks the same regions run after run marks each once. Only a hint: a wrong answer costs
  /// faults, never bits.
  bool first_visit(const std::shared_ptr<const void>& family, int variant, std::size_t i,
                   std::size_t n);

 private:
  std::uintptr_t base_ = 0;              // the buffer's first byte
  std::uintptr_t first_ = 0, end_ = 0;  // the pages the buffer touches: [first_, end_)
  int shift_ = 12;                      // log2 of the page size
  std::vector<std::uint8_t> done_;      // per page: marked by an earlier mark()
  std::vector<std::size_t> fresh_;      // pages marked for the first time since populate()
  std::size_t populated_ = 0;
  struct Visits {
    std::shared_ptr<const void> family;
    int variant;
    std::vector<std::uint8_t> seen;
  };
  std::vector<Visits> visits_;
};

}  // namespace bloomref::detail
