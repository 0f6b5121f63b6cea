#include "batch/progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace bloomref::batch {

std::string format_duration(double seconds) {
  char b[32];
  if (!(seconds >= 0) || !std::isfinite(seconds)) return "--";
  if (seconds < 10) {
    std::snprintf(b, sizeof b, "%.1fs", seconds);
    return b;
  }
  const long long s = std::llround(seconds);
  if (s < 60)
    std::snprintf(b, sizeof b, "%llds", s);
  else if (s < 3600)
    std::snprintf(b, sizeof b, "%lldm%02llds", s / 60, s % 60);
  else
    std::snprintf(b, sizeof b, "%lldh%02lldm", s / 3600, (s % 3600) / 60);
  return b;
}

std::string progress_bar(std::size_t done, std::size_t total, double elapsed, int width,
                         const std::string& noun) {
  char rate[32] = "--/s";
  std::string left = "--";
  if (done > 0 && elapsed > 0) {
    const double per_second = done / elapsed;
    std::snprintf(rate, sizeof rate, per_second >= 10 ? "%.1f/s" : "%.2f/s", per_second);
    left = format_duration((total - std::min(done, total)) / per_second);
  }
  const std::string counts = std::to_string(done) + "/" + std::to_string(total) + " " + noun;
  const std::string tail = "  " + counts + "  " + rate + "  " + left + " left";
  const int bar = std::min(40, width - static_cast<int>(tail.size()) - 2);
  if (bar < 5) return tail.substr(2);
  const int filled =
      total ? static_cast<int>(static_cast<double>(bar) * std::min(done, total) / total) : bar;
  std::string line = "[";
  line += std::string(filled, '=');
  if (filled < bar) line += ">" + std::string(bar - filled - 1, ' ');
  return line + "]" + tail;
}

}  // namespace bloomref::batch
