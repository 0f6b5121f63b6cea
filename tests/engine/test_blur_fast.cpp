// The fast blur (blur_pass_fast) gives blur_pass's bits (any NaN equal to any NaN: test_util.h says
// why): pass by pass on hostile values and
// awkward sizes, with and without the adaptive plan's masks, for every instruction set this CPU
// has; and whole runs on every scene and corpus image with `--blur fast` and `--blur reference`.
#include <catch2/catch.hpp>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <tuple>
#include <vector>

#include "bloomref/executor.h"
#include "bloomref/io.h"
#include "bloomref/sampler.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "bloomref/engine/fast_stages.h"
#include "bloomref/engine/support.h"
#include "bloomref/engine/page_ledger.h"
#include "test_util.h"

using namespace bloomref;

namespace {

// Every instruction set, with the masked tiles found from the mask and from the spans.
std::vector<std::pair<BlurIsa, bool>> isa_and_spans() {
  std::vector<std::pair<BlurIsa, bool>> v;
  for (BlurIsa isa : test::isas())
    for (bool spans : {false, true}) v.emplace_back(isa, spans);
  return v;
}

// Mostly zero (so the masks have something to leave out), with finite values over many
// binades, -0, denormals, 1e38, +-Inf and quiet NaN sprinkled in.
Image hostile_image(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float special[] = {-0.0f,
                           std::numeric_limits<float>::denorm_min(),
                           1e-40f,
                           1e38f,
                           -1e38f,
                           std::numeric_limits<float>::infinity(),
                           -std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::quiet_NaN(),
                           65504.0f,
                           -3.5f};
  Image img(w, h);
  for (float& v : img.values()) {
    const float r = u(rng);
    if (r < 0.85f) v = 0.0f;
    else if (r < 0.97f) v = std::ldexp(u(rng), int(u(rng) * 40.0f) - 20);
    else v = special[int(u(rng) * 10.0f) % 10];
  }
  return img;
}

// Axis orders for the fused blurs: one pass each way, the plan's alternation, two passes
// along the same axis, and more passes than the plan makes.
std::vector<std::vector<Axis>> fused_orders() {
  const Axis H = Axis::horizontal, V = Axis::vertical;
  return {{H}, {V}, {H, V}, {V, V, H}, {H, V, H, V, H, V, H, V, H, V, H}};
}

// What a FusedBlurSink is handed, copied into `image`, with the times each texel was handed,
// whether every block lay inside the image and whether each strip's rows came in order.
struct SinkCapture {
  Image image;
  std::vector<int> times;
  std::vector<std::pair<int, int>> next_row;  // per strip: (x0, next y0)
  bool in_order = true, inside = true;
  std::mutex m;
  SinkCapture(int w, int h) : image(w, h, 7.0f), times(std::size_t(w) * h, 0) {}
  FusedBlurSink sink() {
    return [this](int x0, int x1, int y0, int y1, const float* const* rows) {
      std::lock_guard<std::mutex> lock(m);
      const int w = image.width(), h = image.height();
      inside = inside && 0 <= x0 && x0 < x1 && x1 <= w && 0 <= y0 && y0 < y1 && y1 <= h;
      if (!inside) return;
      auto it = std::find_if(next_row.begin(), next_row.end(),
                             [&](const auto& s) { return s.first == x0; });
      if (it == next_row.end()) it = next_row.insert(next_row.end(), {x0, 0});
      in_order = in_order && it->second == y0;
      it->second = y1;
      for (int y = y0; y < y1; ++y) {
        std::memcpy(image.view().row(y) + 4 * x0, rows[y - y0], std::size_t(x1 - x0) * 16);
        for (int x = x0; x < x1; ++x) ++times[std::size_t(y) * w + x];
      }
    };
  }
  bool each_once() const {
    return std::all_of(times.begin(), times.end(), [](int t) { return t == 1; });
  }
};

}  // namespace

TEST_CASE("blur_pass_fast gives blur_pass's bits on hostile values and awkward sizes",
          "[blur][fast]") {
  // 1920 columns: a tap at x = 1 lands a hair left of texel 0 (w0 = 0); 1080 and 2160 rows
  // and 131, 1920 columns have lookups across the blur that straddle two lines; with 41 columns
  // and 47 rows the lookup across the blur at line 0 is (0, 0) with weights (0, 1): an inexact
  // line whose across mix leaves out its first term.
  const std::pair<int, int> sizes[] = {{1, 1},     {1, 7},    {7, 1},    {3, 5},
                                       {37, 23},   {41, 47},  {257, 131}, {1920, 9},
                                       {9, 1080},  {131, 2160}};
  unsigned seed = 1;
  for (auto [w, h] : sizes) {
    const Image src = hostile_image(w, h, seed++);
    std::vector<std::uint8_t> support(std::size_t(w) * h), active(support.size());
    nonzero_support(src.cview(), support.data(), 1);
    for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
      for (int bits : {0, 8}) {
        for (Axis axis : {Axis::horizontal, Axis::vertical}) {
          BlurPassOptions o{axis, k, bits};
          blur_support<float>(support.data(), active.data(), w, h, o, 1);
          for (bool masked : {false, true}) {
            o.active = masked ? active.data() : nullptr;
            Image ref(w, h), fast(w, h, 7.0f);
            blur_pass(src.cview(), ref.view(), o, 1);
            for (BlurIsa isa : test::isas()) {
              for (int threads : {1, 2}) {
                blur_pass_fast(src.cview(), fast.view(), o, threads, isa);
                INFO(w << "x" << h << " " << k->name << " bits " << bits << " axis "
                       << (axis == Axis::horizontal ? "h" : "v") << " masked " << masked
                       << " isa " << blur_isa_name(isa) << " threads " << threads);
                CHECK(test::same_bits_nan_agnostic(ref.cview(), fast.cview()));
              }
            }
          }
        }
      }
    }
  }
}

TEST_CASE("blur_support is exactly the texels whose lookups read a set texel", "[blur][fast]") {
  // The definition (stages.h), computed texel by texel from the shader's coordinates (uv =
  // (p + 0.5f) / n, taps uv +- offset / n, sampler.h's gl_axis_tap) on sparse random masks:
  // an output texel is set iff one of the texels its taps read (both of each tap, on both lines
  // its lookup across the blur reads) is set. Sizes with lookups straddling two lines (1920,
  // 1080, 131, 2160) and edges closer than the taps' reach.
  const std::pair<int, int> sizes[] = {{1, 1}, {5, 3}, {37, 23}, {300, 131}, {1920, 7},
                                       {9, 1080}, {131, 60}};
  std::mt19937 rng(7);
  for (auto [w, h] : sizes) {
    for (double density : {0.002, 0.05, 0.5}) {
      std::bernoulli_distribution set(density);
      std::vector<std::uint8_t> in(std::size_t(w) * h), out(in.size());
      for (auto& v : in) v = set(rng);
      for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
        for (int bits : {0, 8}) {
          for (Axis axis : {Axis::horizontal, Axis::vertical}) {
            const bool horizontal = axis == Axis::horizontal;
            const int n_along = horizontal ? w : h, n_across = horizontal ? h : w;
            // Per position along: the input positions its taps read; per line across: its two.
            std::vector<std::vector<int>> reads(n_along);
            const float d = 1.0f / float(n_along);
            for (int p = 0; p < n_along; ++p) {
              const float uv = texel_centre(p, n_along);
              std::vector<float> coords = {uv};
              for (std::size_t i = 1; i < k->offsets_f32.size(); ++i) {
                coords.push_back(uv + d * k->offsets_f32[i]);
                coords.push_back(uv - d * k->offsets_f32[i]);
              }
              for (float c : coords) {
                const AxisTap<float> t = gl_axis_tap(c, n_along, bits);
                reads[p].push_back(t.i0);
                reads[p].push_back(t.i1);
              }
            }
            std::size_t expected_count = 0, differ = 0;
            const std::size_t got = blur_support<float>(in.data(), out.data(), w, h,
                                                        BlurPassOptions{axis, k, bits}, 2);
            for (int b = 0; b < n_across; ++b) {
              const AxisTap<float> c = gl_axis_tap(texel_centre(b, n_across), n_across, bits);
              for (int a = 0; a < n_along; ++a) {
                bool any = false;
                for (int s : reads[a])
                  for (int line : {c.i0, c.i1}) {
                    const int x = horizontal ? s : line, y = horizontal ? line : s;
                    any = any || in[std::size_t(y) * w + x];
                  }
                const int x = horizontal ? a : b, y = horizontal ? b : a;
                expected_count += any;
                differ += bool(out[std::size_t(y) * w + x]) != any;
              }
            }
            INFO(w << "x" << h << " density " << density << " " << k->name << " bits " << bits
                   << " axis " << (horizontal ? "h" : "v"));
            CHECK(differ == 0);
            CHECK(got == expected_count);
          }
        }
      }
    }
  }
}

TEST_CASE("a masked fast pass told dst is zero outside leaves those texels alone",
          "[blur][fast]") {
  // The adaptive plan's passes after the first (fast_stages.h: dst_zero_outside): texels
  // outside the mask keep whatever dst held (a sentinel here, to see that nothing wrote them),
  // texels inside get blur_pass's bits; and blur_support's output contains its input, the
  // growth the plan's claim rests on (pass k's buffer was zeroed outside pass k - 2's support).
  // Inactive texels in a tile with an active one are computed, and come out (+0, +0, +0, 1).
  const std::pair<int, int> sizes[] = {{1, 1}, {7, 1}, {3, 5}, {37, 23}, {257, 131},
                                       {1920, 9}, {9, 1080}, {131, 2160}};
  unsigned seed = 90;
  std::size_t total_kept = 0;
  for (auto [w, h] : sizes) {
    // Sparse: the hostile values kept on a few texels only, so whole tiles are inactive.
    Image src = hostile_image(w, h, seed++);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        if ((x / 3 + 7 * (y / 5)) % 61 != 0)
          for (int c = 0; c < 4; ++c) src.view().pixel(x, y)[c] = 0.0f;
    std::vector<std::uint8_t> support(std::size_t(w) * h), active(support.size());
    const std::size_t set = nonzero_support(src.cview(), support.data(), 1);
    for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
      for (int bits : {0, 8}) {
        for (Axis axis : {Axis::horizontal, Axis::vertical}) {
          BlurPassOptions o{axis, k, bits};
          const std::size_t grown = blur_support<float>(support.data(), active.data(), w, h, o, 2);
          INFO(w << "x" << h << " " << k->name << " bits " << bits << " axis "
                 << (axis == Axis::horizontal ? "h" : "v"));
          CHECK(grown >= set);
          std::size_t contained = 0, outside = 0;
          for (std::size_t i = 0; i < support.size(); ++i) {
            contained += !support[i] || active[i];
            outside += !active[i];
          }
          CHECK(contained == support.size());
          o.active = active.data();
          Image ref(w, h);
          blur_pass(src.cview(), ref.view(), o, 1);
          RowSpans spans;
          mask_spans(active.data(), w, h, spans, 1);
          for (auto [isa, with_spans] : isa_and_spans()) {
            FastPassOptions fo;
            fo.dst_zero_outside = true;
            fo.active_spans = with_spans ? &spans : nullptr;
            const float sentinel = -123.25f;
            Image fast(w, h, sentinel);
            blur_pass_fast(src.cview(), fast.view(), o, 2, isa, fo);
            std::size_t kept = 0, zeroed = 0, differ = 0;
            for (int y = 0; y < h; ++y)
              for (int x = 0; x < w; ++x) {
                const float* f = fast.cview().pixel(x, y);
                const float* r = ref.cview().pixel(x, y);
                if (!active[std::size_t(y) * w + x]) {
                  // Untouched, or (in a tile with active texels) computed: (+0, +0, +0, 1).
                  const bool untouched = f[0] == sentinel && f[1] == sentinel &&
                                         f[2] == sentinel && f[3] == sentinel;
                  const float zero_one[4] = {0.0f, 0.0f, 0.0f, 1.0f};
                  kept += untouched;
                  zeroed += std::memcmp(f, zero_one, sizeof zero_one) == 0;
                } else {
                  for (int c = 0; c < 4; ++c)
                    differ += !(std::isnan(f[c]) && std::isnan(r[c])) &&
                              std::memcmp(&f[c], &r[c], sizeof(float)) != 0;
                }
              }
            INFO("isa " << blur_isa_name(isa) << (with_spans ? ", tiles from spans, " : ", ")
                        << outside << " texels outside");
            CHECK(kept + zeroed == outside);
            CHECK(differ == 0);
            total_kept += kept;
          }
        }
      }
    }
  }
  // Not vacuous: whole tiles were left alone.
  CHECK(total_kept > 10000);
}

TEST_CASE("blur_support_spans is blur_support's set, as canonical spans", "[blur][fast]") {
  // blur_support is checked against the definition above; the spans must give the same set and
  // count on every size, density, kernel, subtexel precision, axis and tap table (f32: the
  // shader's coordinates, f64: exact taps), and be sorted, disjoint and not touching. Masks
  // of clustered runs as well as scattered texels (a run's ends are where spans can go wrong).
  const std::pair<int, int> sizes[] = {{1, 1}, {5, 3}, {37, 23}, {300, 131}, {1920, 7},
                                       {9, 1080}, {131, 60}, {2, 2}};
  std::mt19937 rng(11);
  std::size_t compared = 0;
  for (auto [w, h] : sizes) {
    for (double density : {0.0, 0.002, 0.05, 0.5, 1.0}) {
      for (bool runs : {false, true}) {
        std::bernoulli_distribution set(density);
        std::uniform_int_distribution<int> run_length(1, 40);
        std::vector<std::uint8_t> in(std::size_t(w) * h, 0);
        for (std::size_t i = 0; i < in.size();) {
          const int n = runs ? run_length(rng) : 1;
          const bool v = set(rng);
          for (int j = 0; j < n && i < in.size(); ++j, ++i) in[i] = v;
        }
        RowSpans in_spans;
        std::size_t in_count = 0;
        for (std::uint8_t v : in) in_count += v;
        CHECK(mask_spans(in.data(), w, h, in_spans, 2) == in_count);
        for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
          for (int bits : {0, 8}) {
            for (Axis axis : {Axis::horizontal, Axis::vertical}) {
              for (bool f64 : {false, true}) {
                const BlurPassOptions o{axis, k, bits};
                std::vector<std::uint8_t> expected(in.size());
                const std::size_t n =
                    f64 ? blur_support<double>(in.data(), expected.data(), w, h, o, 1)
                        : blur_support<float>(in.data(), expected.data(), w, h, o, 1);
                RowSpans out;
                const std::optional<std::size_t> got =
                    f64 ? blur_support_spans<double>(in_spans, out, w, h, o, 2)
                        : blur_support_spans<float>(in_spans, out, w, h, o, 2);
                INFO(w << "x" << h << " density " << density << (runs ? " runs " : " ")
                       << k->name << " bits " << bits << " axis "
                       << (axis == Axis::horizontal ? "h" : "v") << (f64 ? " f64" : " f32"));
                REQUIRE(got.has_value());
                CHECK(*got == n);
                REQUIRE(out.size() == std::size_t(h));
                std::vector<std::uint8_t> from_spans(in.size(), 0);
                bool canonical = true;
                for (int y = 0; y < h; ++y) {
                  int prev_end = -1;
                  for (const Span& sp : out[y]) {
                    canonical = canonical && sp.x0 >= 0 && sp.x0 < sp.x1 && sp.x1 <= w &&
                                sp.x0 > prev_end;
                    prev_end = sp.x1;
                    for (int x = std::max(sp.x0, 0); x < std::min(sp.x1, w); ++x)
                      from_spans[std::size_t(y) * w + x] = 1;
                  }
                }
                CHECK(canonical);
                CHECK(from_spans == expected);
                ++compared;
              }
            }
          }
        }
      }
    }
  }
  CHECK(compared == 8 * 5 * 2 * 2 * 2 * 2 * 2);
}

TEST_CASE("the adaptive plan's support tracker keeps its mask equal to its spans",
          "[blur][fast]") {
  // Ten passes of the plan from a sparse start: after each, the mask advance returns is the
  // set blur_support gives from the previous mask (computed here independently), and spans()
  // describes that same set, until the tracker turns dense (then null, and the whole image).
  const int w = 641, h = 479;
  std::mt19937 rng(5);
  std::bernoulli_distribution set(0.00003);
  std::vector<std::uint8_t> mask(std::size_t(w) * h);
  for (auto& v : mask) v = set(rng);
  BlurSupportTracker tracker(w, h, 0.5);
  tracker.start(std::vector<std::uint8_t>(mask), 2);
  int tracked = 0;
  for (int pass = 1; pass <= 10; ++pass) {
    const BlurPassOptions o{pass % 2 ? Axis::horizontal : Axis::vertical, &kernel_discrete9(), 0};
    std::vector<std::uint8_t> grown(mask.size());
    const std::size_t n = blur_support<float>(mask.data(), grown.data(), w, h, o, 1);
    const std::uint8_t* active = tracker.advance<float>(o, 2);
    INFO("pass " << pass);
    if (2 * n > mask.size()) {
      CHECK(active == nullptr);
      CHECK(tracker.spans() == nullptr);
      CHECK(tracker.count() == mask.size());
      break;
    }
    REQUIRE(active != nullptr);
    REQUIRE(tracker.spans() != nullptr);
    CHECK(std::equal(grown.begin(), grown.end(), active));
    CHECK(tracker.count() == n);
    std::vector<std::uint8_t> from_spans(mask.size(), 0);
    for (int y = 0; y < h; ++y)
      for (const Span& sp : (*tracker.spans())[y])
        std::fill(from_spans.begin() + std::ptrdiff_t(y) * w + sp.x0,
                  from_spans.begin() + std::ptrdiff_t(y) * w + sp.x1, 1);
    CHECK(from_spans == grown);
    mask = grown;
    ++tracked;
  }
  CHECK(tracked == 10);  // this start stays sparse through all ten passes
}

namespace {

// Whether this kernel faults pages in on madvise(MADV_POPULATE_WRITE) (Linux 5.14+).
bool populate_works() {
#ifdef MADV_POPULATE_WRITE
  const std::size_t page = std::size_t(::sysconf(_SC_PAGESIZE));
  void* m = ::mmap(nullptr, page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (m == MAP_FAILED) return false;
  const bool works = ::madvise(m, page, MADV_POPULATE_WRITE) == 0;
  ::munmap(m, page);
  return works;
#else
  return false;
#endif
}

}  // namespace

TEST_CASE("a page ledger is found by its own buffer, and a moved-from one covers nothing",
          "[blur][fast]") {
  // Two buffers in one block, the second starting 64 bytes into the first one's last page (small
  // images come from the heap one after another): the first ledger covers the second's first
  // byte, but it is not the second's ledger. The executor once took it for it, moved it into
  // the scratch pool with the first image, and then marked pages through the moved-from copy
  // (its range kept, its page marks gone): a crash.
  const std::size_t page = std::size_t(::sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> block(4 * page);
  unsigned char* a = block.data() + (page - reinterpret_cast<std::uintptr_t>(block.data()) % page);
  unsigned char* b = a + page + 64;  // a covers [a, a + page + 64)
  detail::PageLedger la(a, page + 64), lb(b, page);
  CHECK(la.covers(b));
  CHECK(la.of(a));
  CHECK_FALSE(la.of(b));
  CHECK(lb.of(b));
  detail::PageLedger moved = std::move(la);
  CHECK(moved.of(a));
  CHECK(moved.covers(a));
  CHECK_FALSE(la.of(a));
  CHECK_FALSE(la.covers(a));
  CHECK_FALSE(la.covers(b));
  la.mark(a, 16);  // outside every page it covers (none): ignored, no crash
  CHECK_FALSE(la.marked(a));
  moved.mark(a, 16);
  CHECK(moved.marked(a));
}

TEST_CASE("with page ledgers, a sparse fast pass faults in every page it reads or writes first",
          "[blur][fast]") {
  // Two fresh anonymous mappings (no page exists yet) as the adaptive plan's ping-pong pair, a
  // few bright texels, eight passes over the growing support. Before each pass mincore says which
  // pages exist; afterwards every page that came into being (written, or read and so mapped to
  // the zero page) must be one the ledgers marked. Bits: the same as the pass without ledgers
  // into ordinary zeroed images. Sparse: at 1000x300 the ledgers hold under half the pages.
  const std::size_t page = std::size_t(::sysconf(_SC_PAGESIZE));
  for (auto [w, h, seed, first_axis] :
       {std::tuple{1000, 300, 1u, 1}, {1000, 300, 2u, 0}, {1000, 300, 3u, 1}, {1000, 300, 4u, 0},
        {1000, 300, 5u, 1}, {1000, 300, 6u, 0}, {257, 190, 7u, 1}, {257, 190, 8u, 0}}) {
    const std::size_t bytes = std::size_t(w) * h * kChannels * sizeof(float);
    const std::size_t mapped = (bytes + page - 1) / page * page;
    float* buf[2];
    for (float*& b : buf) {
      void* m = ::mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      REQUIRE(m != MAP_FAILED);
      b = static_cast<float*>(m);
    }
    auto view = [&](int i) { return BasicView<float>{w, h, w, buf[i]}; };
    Image plain[2] = {Image::zeroed(w, h), Image::zeroed(w, h)};
    std::mt19937 rng{seed};
    for (int k = 0; k < 5; ++k) {
      const int x = int(rng() % unsigned(w)), y = int(rng() % unsigned(h));
      for (int c = 0; c < 3; ++c) view(0).pixel(x, y)[c] = plain[0].view().pixel(x, y)[c] = 2.0f;
    }
    detail::PageLedger ledger[2] = {detail::PageLedger(buf[0], bytes),
                                    detail::PageLedger(buf[1], bytes)};
    std::vector<std::uint8_t> mask(std::size_t(w) * h), active(mask.size());
    nonzero_support(plain[0].cview(), mask.data(), 1);
    auto resident = [&](int i) {
      std::vector<unsigned char> v(mapped / page);
      REQUIRE(::mincore(buf[i], mapped, v.data()) == 0);
      return v;
    };
    for (int pass = 1; pass <= 8; ++pass) {
      const int from = (pass + 1) % 2, to = pass % 2;
      BlurPassOptions o{(pass + first_axis) % 2 ? Axis::vertical : Axis::horizontal,
                        &kernel_discrete9(), 0};
      blur_support<float>(mask.data(), active.data(), w, h, o, 1);
      RowSpans spans;
      mask_spans(active.data(), w, h, spans, 1);
      o.active = active.data();
      FastPassOptions fo;
      fo.active_spans = &spans;
      fo.dst_zero_outside = true;
      blur_pass_fast(plain[from].cview(), plain[to].view(), o, 2, BlurIsa::best, fo);
      const std::vector<unsigned char> before[2] = {resident(0), resident(1)};
      fo.src_pages = &ledger[from];
      fo.dst_pages = &ledger[to];
      blur_pass_fast(BasicView<const float>{w, h, w, buf[from]}, view(to), o, 2, BlurIsa::best, fo);
      INFO(w << "x" << h << " seed " << seed << " pass " << pass);
      for (int i = 0; i < 2; ++i) {
        const std::vector<unsigned char> after = resident(i);
        std::size_t unmarked = 0;
        for (std::size_t pg = 0; pg < after.size(); ++pg)
          unmarked += (after[pg] & 1) && !(before[i][pg] & 1) &&
                      !ledger[i].marked(reinterpret_cast<char*>(buf[i]) + pg * page);
        CHECK(unmarked == 0);
      }
      CHECK(std::memcmp(buf[to], plain[to].data(), bytes) == 0);
      mask = active;
    }
    // Where the kernel has no MADV_POPULATE_WRITE (before Linux 5.14) nothing is populated; the
    // marks above hold all the same.
    if (populate_works()) {
      for (int i = 0; i < 2; ++i) {
        CHECK(ledger[i].populated() > 0);
        // 257 texels a row is just over a page: there the support reaches most pages.
        if (w == 1000) CHECK(ledger[i].populated() * 2 < mapped / page);
      }
    }
    for (float* b : buf) ::munmap(b, mapped);
  }
}

TEST_CASE("blur_passes_fused gives the pass-by-pass blur's bits", "[blur][fast][fused]") {
  // Several column strips (512 wide) and row chunks (32), strips narrower than a pass's reach,
  // lookups that straddle two lines in both directions (1920, 1080, 131), pass counts from 1
  // to 11 and axis orders the plan does not make.
  const std::pair<int, int> sizes[] = {{1, 1},   {7, 1},      {1, 9},    {37, 23},  {513, 17},
                                       {1100, 37}, {1920, 21}, {9, 1080}, {131, 300},
                                       {533, 19},  {1000, 61}};
  // 533 columns: column 511, the last of the first strip, reads column 512 across a vertical
  // pass (its lookup straddles two columns), which the pass before must compute for the strip.
  // 1000x61: inexact lines both ways: rows with whole groups of 8 positions along them (the
  // group kernel; strips of 500 columns cut groups at 496 and 504) and columns side by side in
  // chunks of 32 rows (the columns kernel): their term orders, weight products, lane selects,
  // form blends and first terms. Where the CPU has AVX-512F, the horizontal passes into rings
  // run along their rows (blur_rows_exact_avx512, two rows at a time and an odd row's tail;
  // the AVX2 and generic builds transpose tiles, so the ISAs' agreement checks it too), and so
  // do their inexact rows (blur_row_inexact_avx512); with AVX2 the inexact rows between rings
  // (blur_row_inexact_avx2). The first pass, when horizontal, packs R, G, B vectors from the
  // RGBA source in registers (under AddressSanitizer, its loads past a row's end are checked
  // too). The hostile values pin what a reordering would change: an Inf times a zero weight in
  // the one-texel lanes, -0 sums, weights swapped across the axis.
  const std::vector<std::vector<Axis>> orders = fused_orders();
  unsigned seed = 40;
  for (auto [w, h] : sizes) {
    Image src = hostile_image(w, h, seed++);
    // A band of -0 (every term of a sum there is -0, and so is the sum: a first term taken as
    // 0 + s(0) w0 would give +0), as wide as a strip.
    for (int y = 0; y < h; ++y)
      for (int x = w / 4; x < w / 4 + std::min(w / 2, 600); ++x)
        for (int c = 0; c < 4; ++c) src.view().pixel(x, y)[c] = -0.0f;
    for (const Kernel* k : {&kernel_discrete9(), &kernel_linear5()}) {
      for (int bits : {0, 8}) {
        for (const std::vector<Axis>& axes : orders) {
          Image a = src, b(w, h);
          for (Axis axis : axes) {
            blur_pass(a.cview(), b.view(), BlurPassOptions{axis, k, bits}, 2);
            std::swap(a, b);
          }
          for (BlurIsa isa : test::isas()) {
            for (int threads : {1, 2}) {
              Image fused(w, h, 7.0f);
              blur_passes_fused(src.cview(), fused.view(), axes, *k, bits, threads, isa);
              INFO(w << "x" << h << " " << k->name << " bits " << bits << " passes "
                     << axes.size() << " isa " << blur_isa_name(isa) << " threads " << threads);
              CHECK(test::same_bits_nan_agnostic(a.cview(), fused.cview()));
              // The same passes handed to a sink: every texel exactly once, rows in order
              // within a strip, the same bits.
              SinkCapture sunk(w, h);
              blur_passes_fused(src.cview(), sunk.sink(), axes, *k, bits, threads, isa);
              CHECK(sunk.inside);
              CHECK(sunk.in_order);
              CHECK(sunk.each_once());
              CHECK(test::same_bits_nan_agnostic(a.cview(), sunk.image.cview()));
            }
          }
        }
      }
    }
  }
}

TEST_CASE("the fused blur's inexact rows keep a lone infinity, bit for bit",
          "[blur][fast][fused]") {
  // 1000x61: row 0's lookup across is all on row 0 at weight 1 (w0 = 0, w1 = 1) and row 31's
  // mixes rows 30 and 31; a horizontal pass between two others runs from ring to ring, along
  // its rows where the CPU has AVX-512F (blur_row_inexact_avx512, whose terms need both
  // weights nonzero: row 0 takes the per-texel path). A term with weight 0 kept would turn an
  // Inf there into NaN (Inf 0), which the NaN-agnostic comparison of hostile images cannot
  // always tell: here the values are finite but for lone infinities far apart, no NaN arises,
  // and every bit must agree.
  const int w = 1000, h = 61;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 4.0f);
  Image src(w, h);
  for (float& v : src.values()) v = u(rng);
  const float inf = std::numeric_limits<float>::infinity();
  for (auto [x, y] : {std::pair{500, 0}, std::pair{100, 31}, std::pair{800, 30}, std::pair{300, 60}})
    for (int c = 0; c < 3; ++c) src.view().pixel(x, y)[c] = c == 1 ? -inf : inf;
  for (const std::vector<Axis>& axes :
       {std::vector<Axis>{Axis::vertical, Axis::horizontal, Axis::vertical},
        std::vector<Axis>{Axis::horizontal, Axis::vertical, Axis::horizontal, Axis::vertical}}) {
    Image a = src, b(w, h);
    for (Axis axis : axes) {
      blur_pass(a.cview(), b.view(), BlurPassOptions{axis, &kernel_discrete9(), 0}, 2);
      std::swap(a, b);
    }
    std::size_t infinite = 0, nan = 0;
    for (float v : a.values()) {
      infinite += std::isinf(v);
      nan += std::isnan(v);
    }
    REQUIRE(infinite > 0);
    REQUIRE(nan == 0);
    for (BlurIsa isa : test::isas()) {
      Image fused(w, h);
      blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0, 1, isa);
      INFO("passes " << axes.size() << " isa " << blur_isa_name(isa));
      CHECK(std::memcmp(a.data(), fused.data(), a.values().size() * sizeof(float)) == 0);
    }
  }
}

TEST_CASE("blur_bright_fused gives extract_bright then the pass-by-pass blur's bits, its sink "
          "writing the scene in place", "[blur][fast][fused]") {
  // The dense plan's bright stage inside the fused blur. The sink here overwrites every texel of
  // the scene it is handed with NaN, as the executor overwrites it with the output: a strip that
  // read its neighbours' columns from the scene after their sinks ran would take NaN for their
  // bright values (the test's 1100x37 and 1920x21 have several strips; 9x1080 one; the columns
  // beside a strip are the passes' reach, 5 a horizontal pass).
  const std::pair<int, int> sizes[] = {{1, 1}, {7, 3}, {37, 23}, {1100, 37}, {1920, 21},
                                       {9, 1080}, {533, 19}};
  const std::vector<std::vector<Axis>> orders = {
      {Axis::horizontal},
      {Axis::vertical, Axis::horizontal},
      {Axis::horizontal, Axis::vertical, Axis::horizontal, Axis::vertical, Axis::horizontal,
       Axis::vertical, Axis::horizontal, Axis::vertical, Axis::horizontal, Axis::vertical}};
  unsigned seed = 90;
  for (auto [w, h] : sizes) {
    const Image scene = hostile_image(w, h, seed++);
    // Thresholds: everything positive bright, the default, and a tie (a texel's own luminance:
    // not bright, strictly greater is).
    std::vector<float> thresholds = {0.0f, 1.0f};
    for (int i = 0; i < w * h; ++i) {
      const float* s = scene.cview().pixel(i % w, i / w);
      const float l = luminance(s[0], s[1], s[2]);
      if (l > 0.0f && std::isfinite(l)) {
        thresholds.push_back(l);
        break;
      }
    }
    for (float threshold : thresholds) {
      Image a(w, h), b(w, h);
      extract_bright(scene.cview(), a.view(), threshold, 1);
      for (const std::vector<Axis>& axes : orders) {
        Image x = a;
        for (Axis axis : axes) {
          blur_pass(x.cview(), b.view(), BlurPassOptions{axis, &kernel_discrete9(), 0}, 2);
          std::swap(x, b);
        }
        for (BlurIsa isa : test::isas()) {
          for (int threads : {1, 2}) {
            Image in_place = scene, sunk(w, h, 7.0f);
            std::vector<int> times(std::size_t(w) * h, 0);
            std::mutex m;
            BasicView<float> target = in_place.view();
            const FusedBlurSink sink = [&](int x0, int x1, int y0, int y1,
                                           const float* const* rows) {
              std::lock_guard<std::mutex> lock(m);
              for (int y = y0; y < y1; ++y) {
                std::memcpy(sunk.view().row(y) + 4 * x0, rows[y - y0],
                            std::size_t(x1 - x0) * 16);
                for (int xx = x0; xx < x1; ++xx) {
                  ++times[std::size_t(y) * w + xx];
                  for (int c = 0; c < 4; ++c)
                    target.pixel(xx, y)[c] = std::numeric_limits<float>::quiet_NaN();
                }
              }
            };
            blur_bright_fused(in_place.cview(), threshold, sink, axes, kernel_discrete9(), 0,
                              threads, isa);
            INFO(w << "x" << h << " threshold " << threshold << " passes " << axes.size()
                   << " isa " << blur_isa_name(isa) << " threads " << threads);
            CHECK(std::all_of(times.begin(), times.end(), [](int t) { return t == 1; }));
            CHECK(test::same_bits_nan_agnostic(x.cview(), sunk.cview()));
          }
        }
      }
    }
  }
}

TEST_CASE("the approximate blur fused gives its pass-by-pass bits", "[blur][approx][fused]") {
  // blur_passes_fused with BlurImpl::approx against blur_pass_approx pass by pass (each
  // instruction set against itself: the generic build does not fuse its multiply-adds). Sizes
  // under the stencil's reach (1, 5, 7: every texel clamped), several strips (1100, 1920: the
  // strips' columns beside them), vertical passes over more than one block of columns (a strip
  // of 550 texels: 1650 floats, blocks of 768) and rows not a whole number of chunks; the rings
  // of 3 floats a texel from the source's 4 and back, and into a sink.
  const std::pair<int, int> sizes[] = {{1, 1},    {7, 1},    {1, 9},     {5, 3},
                                       {37, 23},  {513, 17}, {1100, 37}, {1920, 21},
                                       {9, 1080}, {533, 19}, {1000, 61}};
  const std::vector<std::vector<Axis>> orders = fused_orders();
  unsigned seed = 140;
  for (auto [w, h] : sizes) {
    const Image src = hostile_image(w, h, seed++);
    for (const std::vector<Axis>& axes : orders) {
      for (BlurIsa isa : test::isas()) {
        Image a = src, b(w, h);
        for (Axis axis : axes) {
          blur_pass_approx(a.cview(), b.view(), BlurPassOptions{axis, &kernel_discrete9(), 0}, 2,
                           isa);
          std::swap(a, b);
        }
        for (int threads : {1, 2}) {
          INFO(w << "x" << h << " passes " << axes.size() << " isa " << blur_isa_name(isa)
                 << " threads " << threads);
          Image fused(w, h, 7.0f);
          blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0, threads, isa,
                            BlurImpl::approx);
          CHECK(test::same_bits_nan_agnostic(a.cview(), fused.cview()));
          SinkCapture sunk(w, h);
          blur_passes_fused(src.cview(), sunk.sink(), axes, kernel_discrete9(), 0, threads, isa,
                            BlurImpl::approx);
          CHECK(sunk.inside);
          CHECK(sunk.in_order);
          CHECK(sunk.each_once());
          CHECK(test::same_bits_nan_agnostic(a.cview(), sunk.image.cview()));
        }
      }
    }
    // Stage bright inside: extract_bright, then the passes.
    const std::vector<Axis> hv = {Axis::horizontal, Axis::vertical, Axis::horizontal,
                                  Axis::vertical};
    for (BlurIsa isa : test::isas()) {
      Image a(w, h), b(w, h);
      extract_bright(src.cview(), a.view(), 1.0f, 1);
      for (Axis axis : hv) {
        blur_pass_approx(a.cview(), b.view(), BlurPassOptions{axis, &kernel_discrete9(), 0}, 1,
                         isa);
        std::swap(a, b);
      }
      SinkCapture sunk(w, h);
      blur_bright_fused(src.cview(), 1.0f, sunk.sink(), hv, kernel_discrete9(), 0, 1, isa,
                        BlurImpl::approx);
      INFO(w << "x" << h << " bright, isa " << blur_isa_name(isa));
      CHECK(sunk.each_once());
      CHECK(test::same_bits_nan_agnostic(a.cview(), sunk.image.cview()));
    }
  }
}

TEST_CASE("passes beyond one fused group give the pass-by-pass bits", "[blur][fast][fused]") {
  // blur_passes_fused fuses at most 16 passes (stage bright counted) at once and writes each
  // group into an image the next reads (blur_fused.cpp, kMaxFusedDepth): 15 and 16 passes lie
  // at the boundary with and without bright, 17 and 40 make two and three groups. Into an
  // image, into a sink, with bright in front, exact and approximate.
  const Axis H = Axis::horizontal, V = Axis::vertical;
  const std::pair<int, int> sizes[] = {{37, 23}, {533, 19}};
  unsigned seed = 240;
  for (auto [w, h] : sizes) {
    const Image src = hostile_image(w, h, seed++);
    Image bright(w, h);
    extract_bright(src.cview(), bright.view(), 1.0f, 1);
    for (int n : {15, 16, 17, 40}) {
      std::vector<Axis> axes;
      for (int k = 0; k < n; ++k) axes.push_back(k % 2 ? V : H);
      for (BlurImpl impl : {BlurImpl::fast, BlurImpl::approx}) {
        const BlurIsa isa = test::isas().back();
        const auto by_pass = [&](const Image& from) {
          Image a = from, b(w, h);
          for (Axis axis : axes) {
            const BlurPassOptions o{axis, &kernel_discrete9(), 0};
            if (impl == BlurImpl::approx) blur_pass_approx(a.cview(), b.view(), o, 2, isa);
            else blur_pass(a.cview(), b.view(), o, 2);
            std::swap(a, b);
          }
          return a;
        };
        const Image expected = by_pass(src), expected_bright = by_pass(bright);
        INFO(w << "x" << h << " passes " << n << (impl == BlurImpl::approx ? " approx" : " fast"));
        Image fused(w, h, 7.0f);
        blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0, 2, isa, impl);
        CHECK(test::same_bits_nan_agnostic(expected.cview(), fused.cview()));
        SinkCapture sunk(w, h);
        blur_passes_fused(src.cview(), sunk.sink(), axes, kernel_discrete9(), 0, 2, isa, impl);
        CHECK(sunk.each_once());
        CHECK(test::same_bits_nan_agnostic(expected.cview(), sunk.image.cview()));
        SinkCapture from_bright(w, h);
        blur_bright_fused(src.cview(), 1.0f, from_bright.sink(), axes, kernel_discrete9(), 0, 2,
                          isa, impl);
        CHECK(from_bright.each_once());
        CHECK(test::same_bits_nan_agnostic(expected_bright.cview(), from_bright.image.cview()));
      }
    }
  }
}

TEST_CASE("the approximate blur's fused multiply-adds give the same bits at every width",
          "[blur][approx]") {
  // The 32- and 64-byte builds both fuse each multiply-add (intrinsics, not contraction), so
  // they agree bit for bit; the generic build rounds twice and must differ somewhere (else the
  // comparison could not tell them apart).
  if (!blur_isa_available(BlurIsa::avx2)) {
    WARN("no AVX2 on this CPU: nothing to compare");
    return;
  }
  const int w = 301, h = 67;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 100.0f);
  Image src(w, h);
  for (float& v : src.values()) v = u(rng);
  auto passes = [&](BlurIsa isa) {
    Image a = src, b(w, h);
    for (Axis axis : {Axis::horizontal, Axis::vertical, Axis::horizontal, Axis::vertical}) {
      blur_pass_approx(a.cview(), b.view(), BlurPassOptions{axis, &kernel_discrete9(), 0}, 1,
                       isa);
      std::swap(a, b);
    }
    return a;
  };
  const Image avx2 = passes(BlurIsa::avx2);
  CHECK_FALSE(test::same_bits_nan_agnostic(avx2.cview(), passes(BlurIsa::generic).cview()));
  if (blur_isa_available(BlurIsa::avx512))
    CHECK(test::same_bits_nan_agnostic(avx2.cview(), passes(BlurIsa::avx512).cview()));
}

TEST_CASE("the fused blur's last pass stored past the cache gives the same bits",
          "[blur][fast][fused]") {
  // From 64 MB of output on, the last vertical pass stores its 32-byte-aligned pairs of texels
  // with streaming stores (blur_fused.cpp, kStreamOutBytes). 2100 columns: every strip starts
  // on a 32-byte boundary; 2101: strips of 351 columns and rows of 33616 bytes, aligned and not,
  // so both the streamed and the plain stores write parts of the image.
  for (int w : {2100, 2101}) {
    const int h = 2048;
    REQUIRE(std::size_t(w) * h * 16 >= std::size_t(64) << 20);
    Image src = hostile_image(w, h, 77u + unsigned(w));
    const std::vector<Axis> axes = {Axis::horizontal, Axis::vertical};
    Image a(w, h), b(w, h);
    blur_pass(src.cview(), a.view(), BlurPassOptions{axes[0], &kernel_discrete9(), 0}, 2);
    blur_pass(a.cview(), b.view(), BlurPassOptions{axes[1], &kernel_discrete9(), 0}, 2);
    for (BlurIsa isa : test::isas()) {
      Image fused(w, h, 7.0f);
      blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0, 2, isa);
      INFO(w << "x" << h << " isa " << blur_isa_name(isa));
      CHECK(test::same_bits_nan_agnostic(b.cview(), fused.cview()));
      // The approximate passes stream their last pass's texels too (ApproxRowsJob::stream_dst).
      Image pa(w, h), pb(w, h);
      blur_pass_approx(src.cview(), pa.view(), BlurPassOptions{axes[0], &kernel_discrete9(), 0},
                       2, isa);
      blur_pass_approx(pa.cview(), pb.view(), BlurPassOptions{axes[1], &kernel_discrete9(), 0},
                       2, isa);
      blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0, 2, isa,
                        BlurImpl::approx);
      CHECK(test::same_bits_nan_agnostic(pb.cview(), fused.cview()));
      // A horizontal last pass streams its texels from the horizontal branch.
      blur_passes_fused(src.cview(), fused.view(), {Axis::horizontal}, kernel_discrete9(), 0, 2,
                        isa, BlurImpl::approx);
      CHECK(test::same_bits_nan_agnostic(pa.cview(), fused.cview()));
    }
  }
}

TEST_CASE("the fast and fused blurs take empty images", "[blur][fast][fused]") {
  // 0 columns once made the fused blur's strip width 0 and divided by it (SIGFPE).
  const std::vector<Axis> axes = {Axis::horizontal, Axis::vertical};
  for (auto [w, h] : {std::pair{0, 4}, std::pair{4, 0}, std::pair{0, 0}}) {
    const Image src(w, h);
    for (int threads : {1, 2}) {
      INFO(w << "x" << h << " threads " << threads);
      Image fused(w, h), fast(w, h);
      CHECK_NOTHROW(blur_passes_fused(src.cview(), fused.view(), axes, kernel_discrete9(), 0,
                                      threads));
      CHECK_NOTHROW(blur_pass_fast(src.cview(), fast.view(),
                                   BlurPassOptions{Axis::horizontal, &kernel_discrete9(), 0},
                                   threads));
    }
  }
}

TEST_CASE("the fast blur is not vacuous: a wrong weight is caught", "[blur][fast]") {
  // The comparison above must be able to fail: the same pass with a weight 1 ULP off differs.
  const Image src = hostile_image(64, 48, 99);
  Kernel k = kernel_discrete9();
  BlurPassOptions o{Axis::horizontal, &kernel_discrete9(), 0};
  Image ref(64, 48), fast(64, 48);
  blur_pass(src.cview(), ref.view(), o, 1);
  k.weights_f32[2] = std::nextafter(k.weights_f32[2], 1.0f);
  o.kernel = &k;
  blur_pass_fast(src.cview(), fast.view(), o, 1);
  CHECK_FALSE(test::same_bits_nan_agnostic(ref.cview(), fast.cview()));
}

TEST_CASE("the fast and the reference blur give the same bits on scenes and corpus",
          "[blur][fast][determinism]") {
  const auto scenes = test::scenes_and_corpus({{"demo 1920x1080", make_scene("demo", 1920, 1080)}});
  for (const auto& [name, scene] : scenes) {
    // The fast runs also take the fast finishing stages (f32: composite, tonemap and output in
    // one sweep, finish_fast); the mip method's chain is the same code in both runs, so that
    // case checks the finishing stages alone.
    for (auto [storage, kernel, policy, method] :
         {std::tuple{Storage::f32, KernelName::discrete9, NonFinite::zero, Method::gaussian},
          {Storage::f16, KernelName::linear5, NonFinite::propagate, Method::gaussian},
          {Storage::f32, KernelName::discrete9, NonFinite::propagate, Method::mip}}) {
      BloomParams p;
      p.storage = storage;
      p.kernel = kernel;
      p.nonfinite = policy;
      p.method = method;
      p.plan = PlanMode::full;
      p.blur = BlurImpl::reference;
      const Image ref = test::run_output(scene, p);
      for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
        p.plan = mode;
        p.blur = BlurImpl::fast;
        INFO(name << " " << to_string(storage) << " " << to_string(kernel) << " "
                  << to_string(policy) << " " << to_string(method) << " plan "
                  << to_string(mode));
        CHECK(test::same_bits_nan_agnostic(ref.cview(), test::run_output(scene, p).cview()));
      }
    }
  }
}

TEST_CASE("whole runs with the approximate blur give the same bits fused and stage by stage",
          "[blur][approx][fused][determinism]") {
  // Kept stages (ExecuteOptions::keep_all) make the executor run blur_pass_approx pass by pass
  // (under the adaptive plan over its support) and each finishing stage on its own; without
  // them the passes run fused, stage bright and the finishing stages inside (blur_bright_fused's
  // sink), under both plans. So the adaptive plan's output is the full plan's too.
  const auto scenes = test::scenes_and_corpus({{"demo 1920x1080", make_scene("demo", 1920, 1080)}});
  for (const auto& [name, scene] : scenes) {
    for (PlanMode mode : {PlanMode::full, PlanMode::adaptive}) {
      BloomParams p;
      p.plan = mode;
      p.blur = BlurImpl::approx;
      p.nonfinite = NonFinite::propagate;
      const Plan plan = make_plan(p, scene.cview());
      ExecuteOptions keep;
      keep.keep_all = true;
      const Image staged = execute(plan, scene.cview(), keep).final_image();
      INFO(name << " plan " << to_string(mode));
      CHECK(test::same_bits_nan_agnostic(staged.cview(), test::run_output(scene, p).cview()));
    }
  }
}

TEST_CASE("the approximate blur: impulse response and error against the f64 truth",
          "[blur][approx]") {
  // Binomial row 12 without its two outer terms (LearnOpenGL's 9 taps): C(12, 6 + d) / 4070.
  const double w[5] = {924.0 / 4070, 792.0 / 4070, 495.0 / 4070, 220.0 / 4070, 66.0 / 4070};
  for (BlurIsa isa : test::isas()) {
    for (Axis axis : {Axis::horizontal, Axis::vertical}) {
      // An impulse of 3 at (20, 20) of 41x41: one pass puts v * w_|d| at distance d along the
      // axis (one rounding: the pair sum adds an exact 0), nothing elsewhere.
      Image src(41, 41), out(41, 41);
      src.pixel(20, 20)[0] = src.pixel(20, 20)[1] = src.pixel(20, 20)[2] = 3.0f;
      BlurPassOptions o{axis, &kernel_discrete9(), 0};
      blur_pass_approx(src.cview(), out.view(), o, 1, isa);
      for (int d = -6; d <= 6; ++d) {
        const int x = axis == Axis::horizontal ? 20 + d : 20;
        const int y = axis == Axis::horizontal ? 20 : 20 + d;
        const double expect = std::abs(d) <= 4 ? 3.0 * w[std::abs(d)] : 0.0;
        INFO("isa " << blur_isa_name(isa) << " d " << d);
        CHECK(out.pixel(x, y)[0] == Approx(expect).epsilon(2e-7).margin(0));
        CHECK(out.pixel(x, y)[3] == 1.0f);
      }
      CHECK(out.pixel(19, 19)[0] == 0.0f);
    }
    // Random positive image, 10 passes against the f64 truth (texel-exact taps, exact weights):
    // the f32 sum of 9 terms per pass keeps ~1e-7 relative error, far below GL sampling's 1e-5.
    const int w_ = 67, h_ = 45;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 100.0f);
    Image a(w_, h_), b(w_, h_);
    ImageF64 ta(w_, h_), tb(w_, h_);
    for (std::size_t i = 0; i < a.values().size(); ++i) ta.values()[i] = a.values()[i] = u(rng);
    for (int pass = 0; pass < 10; ++pass) {
      BlurPassOptions o{pass % 2 == 0 ? Axis::horizontal : Axis::vertical, &kernel_discrete9(), 0};
      blur_pass_approx(a.cview(), b.view(), o, 2, isa);
      blur_pass(ta.cview(), tb.view(), o, 2);
      std::swap(a, b);
      std::swap(ta, tb);
    }
    double worst = 0;
    for (std::size_t i = 0; i < a.values().size(); ++i)
      if (i % 4 != 3) worst = std::max(worst, std::fabs(a.values()[i] / ta.values()[i] - 1.0));
    INFO("isa " << blur_isa_name(isa) << " worst relative error " << worst);
    CHECK(worst < 2e-6);
    CHECK(worst > 0.0);  // it is not the f64 computation in disguise
  }
}
