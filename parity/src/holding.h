// The images a comparison holds between stages (internal to parity): the captures, a pool of
// stage-sized buffers, and when each image may be released.
#pragma once

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/plan.h"
#include "chain.h"

namespace bloomref::parity::detail {

// A capture the comparison reads: a view of the caller's image, or one it loaded and owns.
struct Held {
  ConstImageView view;
  Image owned;
  int code_bits = 0;
  bool srgb = false;
};

// Stage-sized buffers the stages done hand back and the next ones take, instead of freeing them
// and mapping new ones: a new buffer is faulted in page by page as it is first written (check
// maps every block from 1 MiB, cmd_check.cpp), which took most of check's system time. Emptied
// before each stage is judged, so that it never adds to the peak.
class ImagePool {
 public:
  Image take(int w, int h) {
    for (auto it = pool_.begin(); it != pool_.end(); ++it)
      if (it->width() == w && it->height() == h) {
        Image img = std::move(*it);
        pool_.erase(it);
        return img;
      }
    return Image::uninitialised(w, h);
  }
  void give(Image& img) {
    if (!img.empty() && pool_.size() < kKeep) pool_.push_back(std::move(img));
    img = Image();
  }
  void give(Held& h) { give(h.owned); }
  void clear() { pool_.clear(); }

 private:
  static constexpr std::size_t kKeep = 4;
  std::vector<Image> pool_;
};

// The images a comparison holds, each released once no later stage needs it: the captures
// (loaded when reached), the stages without capture (the oracle's, stored) and the error they
// carry, the oracle's full run and its end-to-end bounds.
class Streams {
 public:
  Streams(const Plan& plan, const std::vector<std::string>& captured, bool causes) {
    const auto& st = plan.stages;
    for (std::size_t i = 0; i < st.size(); ++i) index_[st[i].name] = static_cast<int>(i);
    for (const std::string& c : captured) captured_[c] = true;
    // A stage is needed until the last stage that reads it. The isolated chain (captures,
    // recomputed stages) is kept longer for the cause hypotheses, which recompute a failing
    // stage from the captures before it: until the first capture downstream of each uncaptured
    // reader has been judged, and pass k - 2 until pass k.
    for (int i = static_cast<int>(st.size()) - 1; i >= 0; --i)
      for (const std::string& in : stage_inputs(plan, st[i])) {
        read_[in] = std::max(get(read_, in), i);
        int until = i;
        if (causes && !captured_.count(st[i].name)) until = std::max(until, get(chain_, st[i].name));
        chain_[in] = std::max(get(chain_, in), until);
      }
    if (causes)
      for (const StageSpec& s : st) {
        if (s.kind == StageKind::blur && s.pass >= 3) {
          const std::string back = "blur." + std::to_string(s.pass - 2);
          chain_[back] = std::max(get(chain_, back), index_[s.name]);
        }
        // A mip stage's source's own source: the level one further along the chain, which
        // mip-level-offset reads instead.
        if (s.kind == StageKind::down || s.kind == StageKind::up) {
          const StageSpec* src = find_stage(plan, stage_inputs(plan, s)[0]);
          if (src && !stage_inputs(plan, *src).empty()) {
            const std::string back = stage_inputs(plan, *src)[0];
            chain_[back] = std::max(get(chain_, back), index_[s.name]);
          }
        }
      }
  }
  bool captured(const std::string& n) const { return captured_.count(n) > 0; }
  /// Whether a stage after `index` reads `n`.
  bool read_after(const std::string& n, int index) const { return get(read_, n) > index; }
  /// Hands `recycle` every image of the isolated chain no stage after `done` (an index into
  /// the plan) needs, and drops it from its map.
  template <class Recycle, class... Maps>
  void release_chain(int done, Recycle recycle, Maps&... maps) {
    (release_in(chain_, done, recycle, maps), ...);
  }
  /// The same for the images only the stages that read them need: the oracle's full run, its
  /// bounds, the error stages without capture carry.
  template <class Recycle, class... Maps>
  void release_read(int done, Recycle recycle, Maps&... maps) {
    (release_in(read_, done, recycle, maps), ...);
  }

 private:
  static int get(const std::map<std::string, int>& m, const std::string& n) {
    const auto it = m.find(n);
    return it == m.end() ? -1 : it->second;
  }
  template <class Recycle, class Map>
  static void release_in(const std::map<std::string, int>& need, int done, Recycle& recycle,
                         Map& m) {
    for (auto it = m.begin(); it != m.end();) {
      if (get(need, it->first) > done) {
        ++it;
        continue;
      }
      recycle(it->second);
      it = m.erase(it);
    }
  }
  std::map<std::string, int> index_, read_, chain_;
  std::map<std::string, bool> captured_;
};

}  // namespace bloomref::parity::detail
