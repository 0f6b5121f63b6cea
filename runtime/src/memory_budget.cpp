#include "bloomref/memory_budget.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "bloomref/error.h"
#include "bloomref/plan.h"

namespace bloomref {
namespace {

constexpr std::uint64_t kMiB = std::uint64_t(1) << 20;
// Fused blur groups (engine/src/blur_fused.cpp, kMaxFusedDepth): beyond this many passes the
// fused blur holds two more whole float images.
constexpr int kFusedPassesInOneGroup = 15;

// A limit from a cgroup file: a number of bytes, or "max" / an absurd value for none.
std::uint64_t cgroup_limit(const char* path) {
  std::ifstream f(path);
  std::string v;
  if (!(f >> v) || v.empty() || !std::isdigit(static_cast<unsigned char>(v[0]))) return 0;
  try {
    return std::stoull(v);
  } catch (...) {
    return 0;
  }
}

}  // namespace

WorkingSet working_set(const BloomParams& p, int width, int height, int kept_traces, bool gl) {
  const std::uint64_t pixels = std::uint64_t(std::max(width, 0)) * std::uint64_t(std::max(height, 0));
  const std::uint64_t f32_image = pixels * 4 * sizeof(float);
  WorkingSet ws;
  ws.image_bytes = p.precision == Precision::f64 ? 2 * f32_image : f32_image;
  const std::uint64_t stages = stage_names(p, std::max(width, 1), std::max(height, 1)).size();
  const std::uint64_t images = kept_traces > 0 ? std::uint64_t(kept_traces) * stages + 1 : 4;
  // The f32 executor takes the loaded input over; f64 converts it, keeping it meanwhile.
  const std::uint64_t input = p.precision == Precision::f64 ? 1 : 0;
  const std::uint64_t groups =
      p.method == Method::gaussian && p.passes > kFusedPassesInOneGroup ? 2 : 0;
  ws.images = double(images) + double(input + groups) * double(f32_image) / double(ws.image_bytes);
  ws.bytes = (gl ? 128 : 64) * kMiB + images * ws.image_bytes + (input + groups) * f32_image +
             pixels * 3;  // the PNG's 8-bit RGB
  return ws;
}

std::uint64_t available_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  std::uint64_t m = pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : 0;
  for (const char* f : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    const std::uint64_t c = cgroup_limit(f);
    if (c > 0 && (m == 0 || c < m)) m = c;
  }
  return m;
}

std::uint64_t default_memory_budget() {
  const std::uint64_t m = available_memory_bytes();
  return m == 0 ? ~std::uint64_t(0) : m / 5 * 4;
}

std::uint64_t peak_rss_bytes() {
  std::ifstream f("/proc/self/status");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("VmHWM:", 0) == 0) {
      try {
        return std::stoull(line.substr(6)) * 1024;  // "VmHWM:    12345 kB"
      } catch (...) {
        break;
      }
    }
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<std::uint64_t>(u.ru_maxrss) * 1024;  // Linux: KiB
}

std::uint64_t parse_byte_size(const std::string& text, const std::string& option) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (...) {
    used = 0;
  }
  std::string unit = text.substr(used);
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return std::toupper(c); });
  if (unit.size() > 1 && (unit.substr(1) == "B" || unit.substr(1) == "IB")) unit.resize(1);
  if (unit == "B") unit.clear();
  static const std::string units = "KMGT";
  const std::size_t u = unit.empty() ? std::string::npos : units.find(unit);
  if (used == 0 || !std::isfinite(v) || v <= 0 || (!unit.empty() && (unit.size() != 1 || u == std::string::npos)))
    throw ParamError(option + " '" + text + "' is not a size such as 512M, 8G or 1.5T");
  const double bytes = v * std::pow(1024.0, unit.empty() ? 0.0 : double(u + 1));
  if (bytes >= 1.8e19) throw ParamError(option + " '" + text + "' is too large");
  return static_cast<std::uint64_t>(bytes);
}

std::string byte_size_text(std::uint64_t bytes) {
  static const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 6) {
    v /= 1024.0;
    ++u;
  }
  char buf[64];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.3g %s", v, units[u]);
  return buf;
}

}  // namespace bloomref
