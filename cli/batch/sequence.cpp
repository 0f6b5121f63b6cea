#include "batch/sequence.h"

#include <fcntl.h>
#include <openexr.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "batch/progress.h"
#include "bloomref/error.h"
#include "bloomref/gpu/context.h"
#include "bloomref/parallel.h"

extern char** environ;

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace bloomref::cli {
namespace {

// Set by the handler; the loop reads it between items.
std::atomic<int> g_signal{0};

void on_signal(int sig) {
  g_signal = sig;
  static const char msg[] =
      "\nbloomref: stopping after the items in flight (again to stop at once)\n";
  [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, msg, sizeof msg - 1);
}

// SIGINT and SIGTERM (Ctrl-C; scancel, a Kubernetes pod's deletion) while a batch runs. The
// handler resets itself (SA_RESETHAND), so a second signal stops the process at once.
class SignalScope {
 public:
  SignalScope() {
    g_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = on_signal;
    sa.sa_flags = SA_RESETHAND;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~SignalScope() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

 private:
  struct sigaction old_int_ {
  }, old_term_{};
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Terminal width from $COLUMNS, else 80.
int terminal_width() {
  if (const char* c = std::getenv("COLUMNS")) {
    const int w = std::atoi(c);
    if (w >= 20) return w;
  }
  return 80;
}

// Every chunk of every part of an EXR lies within the file: the offset table is whole and the
// chunk furthest in ends before the end of the file. (OpenEXR's InputFile::isComplete checks
// only the offset table, which a file cut short keeps: measured here on a 48x40 file cut in half.)
bool exr_complete(const std::string& path, std::uintmax_t size) {
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = [](exr_const_context_t, exr_result_t, const char*) {};
  exr_context_t ctx = nullptr;
  if (exr_start_read(&ctx, path.c_str(), &init) != EXR_ERR_SUCCESS) {
    exr_finish(&ctx);
    return false;
  }
  bool ok = true;
  std::uint64_t end = 0;
  int parts = 0;
  ok = exr_get_count(ctx, &parts) == EXR_ERR_SUCCESS;
  for (int p = 0; ok && p < parts; ++p) {
    exr_storage_t storage{};
    exr_attr_box2i_t dw{};
    int32_t lines = 0;
    ok = exr_get_storage(ctx, p, &storage) == EXR_ERR_SUCCESS &&
         storage == EXR_STORAGE_SCANLINE &&  // bloomref writes scanline files only
         exr_get_data_window(ctx, p, &dw) == EXR_ERR_SUCCESS &&
         exr_get_scanlines_per_chunk(ctx, p, &lines) == EXR_ERR_SUCCESS && lines > 0;
    for (int y = dw.min.y; ok && y <= dw.max.y; y += lines) {
      exr_chunk_info_t ci{};
      ok = exr_read_scanline_chunk_info(ctx, p, y, &ci) == EXR_ERR_SUCCESS;
      end = std::max<std::uint64_t>(end, ci.data_offset + ci.packed_size);
    }
  }
  exr_finish(&ctx);
  return ok && end <= size;
}

}  // namespace

void SequenceOptions::add_to(CLI::App& app, bool for_run) {
  app.add_option("--frames", frames,
                 "frames of a sequence: 1-240, 1-100x2,120 (oiiotool's syntax); IN and outputs "
                 "name them as 'shot.####.exr' or 'shot.%04d.exr'");
  app.add_option("--shard", shard,
                 "take every N-th item from K (K/N, 1-based), or auto: from Slurm, Kubernetes, "
                 "GitLab, Bazel, GoogleTest, Buildkite or CircleCI variables (docs/cluster.md)");
  app.add_option("--shard-count", shard_count,
                 "with --shard auto on a Kubernetes Indexed Job: the Job's completions");
  app.add_option("--progress", progress,
                 "auto (a bar on a terminal, else a line per item) | bar | lines | none")
      ->capture_default_str();
  if (!for_run) return;
  app.add_flag("--resume", resume, "skip frames whose outputs already exist and are complete");
  // Measured on the project's 2-core machine (benchmarks/sequence.sh): two frames at once were
  // no faster than one frame on both threads, at 256x256 or at 3840x2160.
  app.add_option("--jobs", jobs, "frames at once, the threads shared among them")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
}

batch::Environment process_environment() {
  batch::Environment env;
  for (char** e = environ; e && *e; ++e) {
    const std::string kv = *e;
    const auto eq = kv.find('=');
    if (eq != std::string::npos) env[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  return env;
}

std::vector<int> sequence_frames(const SequenceOptions& o, const batch::FramePattern& pattern,
                                 const std::string& what) {
  if (!o.frames.empty()) return batch::parse_frame_list(o.frames);
  if (!pattern.has_wildcard())
    throw ParamError("--frames is needed: " + what + " names no frame sequence");
  // No --frames: the frames whose files (or folders) exist, as oiiotool finds them.
  std::string text = pattern.text();
  while (text.size() > 1 && text.back() == '/') text.pop_back();
  const batch::FramePattern scan = batch::FramePattern::parse(text);
  const fs::path p(text);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::vector<int> frames;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name =
        p.has_parent_path() ? (dir / e.path().filename()).string() : e.path().filename().string();
    if (const auto f = scan.frame_of(name)) frames.push_back(*f);
  }
  if (frames.empty())
    throw ParamError("no file matches " + what + " '" + pattern.text() +
                     "'; name the frames with --frames (e.g. --frames 1-240)");
  std::sort(frames.begin(), frames.end());
  return frames;
}

ordered_json ItemSelection::json(bool finished, bool interrupted) const {
  ordered_json s = nullptr;
  if (shard)
    s = {{"index", shard->index + 1},
         {"count", shard->count},
         {"label", shard->label()},
         {"source", shard->source}};
  return {{"items_total", ids.size()},     {"item_ids", ids},      {"shard", s},
          {"items_in_shard", mine.size()}, {"finished", finished}, {"interrupted", interrupted}};
}

ItemSelection select_items(std::vector<std::string> ids, const SequenceOptions& o) {
  ItemSelection s;
  s.ids = std::move(ids);
  s.shard = batch::resolve_shard(o.shard, o.shard_count, process_environment());
  if (s.shard) {
    s.mine = batch::shard_positions(s.ids.size(), *s.shard);
    // Bazel asks a sharded test to touch this file to say it understood the sharding.
    if (!s.shard->status_file.empty()) std::ofstream(s.shard->status_file, std::ios::app);
  } else {
    for (std::size_t i = 0; i < s.ids.size(); ++i) s.mine.push_back(i);
  }
  return s;
}

const char* to_string(ItemOutcome::Status s) {
  switch (s) {
    case ItemOutcome::Status::done:
      return "done";
    case ItemOutcome::Status::resumed:
      return "resumed";
    case ItemOutcome::Status::error:
      return "error";
    case ItemOutcome::Status::not_run:
      return "not-run";
  }
  return "?";
}

int batch_exit_code(const std::vector<ItemOutcome>& outcomes, bool interrupted) {
  if (interrupted) return 130;
  int code = 0;
  for (const ItemOutcome& o : outcomes)
    if (o.status == ItemOutcome::Status::error) code = std::max(code, o.exit_code);
  return code;
}

namespace {

// --progress as it applies here: auto is a bar on a terminal, lines otherwise; --quiet is none.
std::string progress_mode(const std::string& progress, bool quiet) {
  std::string mode = quiet ? "none" : progress;
  if (mode == "auto") mode = ::isatty(STDERR_FILENO) ? "bar" : "lines";
  if (mode != "bar" && mode != "lines" && mode != "none")
    throw ParamError("--progress '" + progress + "' is not one of: auto, bar, lines, none");
  return mode;
}

ItemOutcome item_error(const std::string& message, int code) {
  ItemOutcome o;
  o.status = ItemOutcome::Status::error;
  o.message = message;
  o.exit_code = code;
  return o;
}

// One item, timed. A bad input or file of this item is its error (exit 2) and the others go
// on; GL missing and bad parameters concern every item and stop the loop (rethrown).
template <class Fn>
ItemOutcome run_item(const Fn& fn, std::size_t i, int threads) {
  const auto t0 = std::chrono::steady_clock::now();
  ItemOutcome o;
  try {
    o = fn(i, threads);
  } catch (const gpu::GlUnavailable&) {
    throw;
  } catch (const ParamError&) {
    throw;
  } catch (const Error& e) {
    o = item_error(e.what(), 2);
  } catch (const std::bad_alloc&) {
    o = item_error("out of memory", 4);
  } catch (const std::exception& e) {
    o = item_error(std::string("internal error: ") + e.what(), 4);
  }
  if (o.ms == 0) o.ms = 1000 * seconds_since(t0);
  return o;
}

}  // namespace

std::vector<ItemOutcome> BatchLoop::run(const std::vector<std::string>& labels, bool& interrupted) {
  const std::size_t n = labels.size();
  std::vector<ItemOutcome> out(n);
  const std::string mode = progress_mode(progress, quiet);

  const SignalScope signals;
  const auto t0 = std::chrono::steady_clock::now();
  auto last_checkpoint = t0;
  std::mutex lock;
  std::size_t done = 0;
  std::exception_ptr fatal;
  std::atomic<std::size_t> next{0};
  const int all_threads = resolve_threads(threads);

  auto draw = [&] {  // under the lock
    if (mode == "bar")
      std::fprintf(
          stderr, "\r%s\033[K",
          batch::progress_bar(done, n, seconds_since(t0), terminal_width() - 1, noun).c_str());
  };
  auto finish_item = [&](std::size_t i, ItemOutcome o) {
    std::lock_guard<std::mutex> g(lock);
    ++done;
    if (o.status == ItemOutcome::Status::error)
      std::fprintf(stderr, "%sbloomref: %s %s: %s\n", mode == "bar" ? "\r\033[K" : "",
                   noun == "frames" ? "frame" : "item", labels[i].c_str(), o.message.c_str());
    if (mode == "lines") {
      std::printf("[%zu/%zu] %s: %s", done, n, labels[i].c_str(), to_string(o.status));
      if (o.status == ItemOutcome::Status::done) std::printf(", %.0f ms", o.ms);
      if (!o.message.empty() && o.status != ItemOutcome::Status::error)
        std::printf(" (%s)", o.message.c_str());
      std::printf("\n");
      std::fflush(stdout);
    }
    out[i] = std::move(o);
    draw();
    if (checkpoint && seconds_since(last_checkpoint) >= 2) {
      checkpoint(out);
      last_checkpoint = std::chrono::steady_clock::now();
    }
  };
  auto run_one = [&](std::size_t i, int t) { finish_item(i, run_item(fn, i, t)); };
  auto worker = [&](int t) {
    try {
      while (g_signal == 0) {
        {
          std::lock_guard<std::mutex> g(lock);
          if (fatal) return;
        }
        const std::size_t i = next++;
        if (i >= n) return;
        run_one(i, t);
      }
    } catch (...) {
      std::lock_guard<std::mutex> g(lock);
      if (!fatal) fatal = std::current_exception();
    }
  };

  {
    std::lock_guard<std::mutex> g(lock);
    draw();
  }
  const int j = std::max(1, jobs);
  if (j == 1) {
    worker(threads);
  } else {
    std::vector<std::thread> pool;
    for (int k = 0; k < j; ++k) pool.emplace_back(worker, std::max(1, all_threads / j));
    for (std::thread& t : pool) t.join();
  }
  if (mode == "bar") std::fprintf(stderr, "\n");
  interrupted = g_signal != 0;
  if (fatal) std::rethrow_exception(fatal);
  if (checkpoint) {
    std::lock_guard<std::mutex> g(lock);
    checkpoint(out);
  }
  return out;
}

bool image_complete(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".png") {
    // The last chunk of a PNG: length 0, "IEND", CRC AE 42 60 82 (PNG specification, 11.2.5).
    static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (!f || f.tellg() < 20) return false;
    f.seekg(-12, std::ios::end);
    unsigned char tail[12];
    f.read(reinterpret_cast<char*>(tail), 12);
    return f && std::equal(tail, tail + 12, iend);
  }
  return exr_complete(path, fs::file_size(path, ec));
}

}  // namespace bloomref::cli
