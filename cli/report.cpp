#include "report.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "bloomref/error.h"
#include "bloomref/io.h"
#include "bloomref/output_files.h"
#include "escape.h"

namespace fs = std::filesystem;

namespace bloomref::cli {
namespace {

constexpr int kPreview = 384;  // longest side of the previews embedded in index.html

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::uint32_t val = 0;  // unsigned: the bits shifted out at the top are dropped, not overflow
  int bits = -6;
  for (unsigned char c : in) {
    val = (val << 8) + c;
    bits += 8;
    while (bits >= 0) {
      out.push_back(t[(val >> bits) & 0x3F]);
      bits -= 6;
    }
  }
  if (bits > -6) out.push_back(t[((val << 8) >> (bits + 8)) & 0x3F]);
  while (out.size() % 4) out.push_back('=');
  return out;
}


std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

// Scene-referred values shown as x / (1 + x), gamma 2.2 (the display-referred stages pass
// through unchanged); NaN magenta, Inf white.
Image display(const Image& img, bool scene_referred) {
  Image out(img.width(), img.height());
  for (std::size_t i = 0; i < img.pixel_count(); ++i) {
    const float* s = img.data() + i * 4;
    float* d = out.data() + i * 4;
    bool nan = false, inf = false;
    for (int c = 0; c < 3; ++c) {
      nan |= std::isnan(s[c]);
      inf |= std::isinf(s[c]);
      const float v = std::max(s[c], 0.0f);
      d[c] = scene_referred ? std::pow(v / (1 + v), 1 / 2.2f) : v;
    }
    if (nan) d[0] = 1, d[1] = 0, d[2] = 1;
    else if (inf) d[0] = d[1] = d[2] = 1;
    d[3] = 1;
  }
  return out;
}

// Signed difference device - oracle: red where the device is larger, blue where smaller, scaled to the
// stage's largest |difference| (stated in the page).
Image signed_diff(const Image& gl, const Image& oracle, double& scale) {
  scale = 0;
  for (std::size_t i = 0; i < gl.values().size(); ++i)
    if (i % 4 != 3 && std::isfinite(gl.values()[i]) && std::isfinite(oracle.values()[i]))
      scale = std::max(scale, double(std::fabs(gl.values()[i] - oracle.values()[i])));
  Image out(gl.width(), gl.height());
  for (std::size_t i = 0; i < gl.pixel_count(); ++i) {
    double d = 0;
    for (int c = 0; c < 3; ++c) {
      const double v = double(gl.data()[i * 4 + c]) - oracle.data()[i * 4 + c];
      if (std::isfinite(v) && std::fabs(v) > std::fabs(d)) d = v;
    }
    const float m = scale > 0 ? static_cast<float>(std::fabs(d) / scale) : 0.0f;
    float* o = out.data() + i * 4;
    o[0] = d > 0 ? m : 0;
    o[1] = 0;
    o[2] = d < 0 ? m : 0;
    o[3] = 1;
  }
  return out;
}

// error / bound per pixel (largest channel), raw, and as a heat map: black 0, yellow at 1,
// red and then white beyond (values above 1 stand out); the pass/fail mask beside it.
void ratio_images(const Image& gl, const Image& oracle, const Image& bound, Image& raw,
                  Image& heat, Image& mask) {
  raw = Image(gl.width(), gl.height());
  heat = Image(gl.width(), gl.height());
  mask = Image(gl.width(), gl.height());
  for (std::size_t i = 0; i < gl.pixel_count(); ++i) {
    double r = 0;
    bool mismatch = false;
    for (int c = 0; c < 3; ++c) {
      const double g = gl.data()[i * 4 + c], o = oracle.data()[i * 4 + c],
                   b = bound.data()[i * 4 + c];
      if (std::isnan(g) != std::isnan(o) || (std::isinf(g) != std::isinf(o) && std::fabs(g - o) > b)) {
        mismatch = true;
        continue;
      }
      if (!std::isfinite(g) || !std::isfinite(o)) continue;
      const double e = std::fabs(g - o);
      r = std::max(r, e == 0 ? 0.0 : (b > 0 ? e / b : 1e30));
    }
    float* p = raw.data() + i * 4;
    p[0] = p[1] = p[2] = static_cast<float>(mismatch ? INFINITY : r);
    p[3] = 1;
    float* h = heat.data() + i * 4;
    const float t = static_cast<float>(std::min(r, 1.0));
    if (mismatch) h[0] = 1, h[1] = 0, h[2] = 1;
    else if (r <= 1) h[0] = t, h[1] = t, h[2] = 0;
    else h[0] = 1, h[1] = static_cast<float>(std::min(1.0, std::log10(r) / 2)), h[2] = h[1];
    h[3] = 1;
    float* k = mask.data() + i * 4;
    const bool bad = mismatch || r > 1;
    k[0] = bad ? 1.0f : 0.0f;
    k[1] = bad ? 0.0f : 0.35f;
    k[2] = mismatch ? 1.0f : 0.0f;
    k[3] = 1;
  }
}

// A preview no larger than kPreview: each preview pixel takes the brightest source pixel of its
// block (so one failing pixel still shows), or the block's mean for pictures.
Image preview(const Image& img, bool keep_peaks) {
  const int f = std::max(1, (std::max(img.width(), img.height()) + kPreview - 1) / kPreview);
  if (f == 1) return img;
  const int w = (img.width() + f - 1) / f, h = (img.height() + f - 1) / f;
  Image out(w, h, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float acc[4] = {0, 0, 0, 0}, best = -1;
      int n = 0;
      for (int yy = y * f; yy < std::min(img.height(), (y + 1) * f); ++yy)
        for (int xx = x * f; xx < std::min(img.width(), (x + 1) * f); ++xx) {
          const float* p = img.pixel(xx, yy);
          if (keep_peaks) {
            const float s = p[0] + p[1] + p[2];
            if (s > best) {
              best = s;
              std::copy(p, p + 4, acc);
            }
          } else {
            for (int c = 0; c < 4; ++c) acc[c] += p[c];
            ++n;
          }
        }
      float* o = out.pixel(x, y);
      for (int c = 0; c < 4; ++c) o[c] = keep_peaks ? acc[c] : acc[c] / n;
    }
  return out;
}

std::string png_data_uri(const Image& img) {
  return "data:image/png;base64," + base64(encode_png(img.cview()));
}

std::string histogram_svg(const std::vector<std::uint64_t>& h) {
  std::uint64_t m = 1;
  for (auto v : h) m = std::max(m, v);
  std::string s = "<svg width='360' height='90' xmlns='http://www.w3.org/2000/svg'>";
  for (std::size_t i = 0; i < h.size(); ++i) {
    // log scale so that a handful of outliers stays visible next to millions of zeros
    const double bar = h[i] ? 70.0 * std::log10(1.0 + h[i]) / std::log10(1.0 + m) : 0.0;
    s += "<rect x='" + std::to_string(4 + i * 21) + "' y='" + num(72 - bar) + "' width='18' height='" +
         num(bar) + "' fill='" + (i == 8 ? "#6a6" : "#c84") + "'><title>" +
         std::to_string(int(i) - 8) + " ULP: " + std::to_string(h[i]) + "</title></rect>";
    s += "<text x='" + std::to_string(8 + i * 21) + "' y='86' font-size='9'>" +
         (i == 0 ? "&lt;-7" : i == 16 ? "&gt;7" : std::to_string(int(i) - 8)) + "</text>";
  }
  return s + "</svg>";
}

const char* kStyle =
    "body{font:14px sans-serif;margin:20px;background:#fafafa}"
    "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 6px;"
    "text-align:right}th{background:#eee}.PASS{color:#070}.WARN{color:#a60}.FAIL{color:#c00;"
    "font-weight:bold}img{image-rendering:pixelated;border:1px solid #999;max-width:384px}"
    "figure{display:inline-block;margin:4px;vertical-align:top}figcaption{font-size:12px}"
    "section{background:#fff;border:1px solid #ddd;padding:10px;margin:12px 0}"
    ".first{border:3px solid #c00}.cause{background:#fff4e0;padding:6px}";

std::string percent(double f) {
  char b[32];
  std::snprintf(b, sizeof b, f >= 0.9995 && f < 1 ? "%.3f%%" : "%.1f%%", 100 * f);
  return b;
}

void write_head(std::ostringstream& html, const std::string& source, const std::string& renderer,
                const Plan& plan, const parity::ParityResult& r, const std::string& fault) {
  const std::string first = r.first_divergent_stage.value_or("");
  html << "<!doctype html><html><head><meta charset='utf-8'><title>bloomref: " << escape::html(source)
       << "</title><style>" << kStyle << "</style></head><body>";
  html << "<h1>bloomref: " << escape::html(source) << "</h1><p>" << escape::html(renderer) << "<br>profile "
       << escape::html(r.profile.name) << " (" << escape::html(r.profile.source) << ")<br>"
       << plan.facts.width << "x" << plan.facts.height << ", " << plan.params.passes << " passes, "
       << to_string(plan.params.kernel) << ", storage " << to_string(plan.params.storage)
       << (fault == "none" ? std::string() : ", injected fault <b>" + escape::html(fault) + "</b>")
       << "</p><h2 class='" << parity::to_string(r.verdict) << "'>verdict "
       << parity::to_string(r.verdict) << "; first divergent stage: "
       << (first.empty() ? "none" : "<a href='#stage-" + escape::html(first) + "'>" + escape::html(first) + "</a>")
       << "</h2>";
}

void write_summary(std::ostringstream& html, const parity::ParityResult& r) {
  html << "<table><tr><th>stage</th><th>isolated</th><th>max |err|</th><th>max f16 ULP</th>"
          "<th>largest err/bound</th><th>values over bound</th><th>end to end</th>"
          "<th>largest err/bound</th><th style='text-align:left'>cause</th></tr>";
  for (std::size_t i = 0; i < r.isolated.size(); ++i) {
    const auto& s = r.isolated[i];
    const auto& e = r.end_to_end[i];
    html << "<tr><td><a href='#stage-" << escape::html(s.stage) << "'>" << escape::html(s.stage) << "</a></td><td class='"
         << parity::to_string(s.verdict) << "'>" << parity::to_string(s.verdict) << "</td><td>"
         << num(s.max_abs) << "</td><td>" << num(s.max_ulp16) << "</td><td>" << num(s.max_ratio)
         << "</td><td>" << s.over_bound + s.nonfinite_mismatch << "</td><td class='"
         << parity::to_string(e.verdict) << "'>" << parity::to_string(e.verdict) << "</td><td>"
         << num(e.max_ratio) << "</td><td style='text-align:left'>" << escape::html(cause_line(s))
         << "</td></tr>";
  }
  html << "</table><p>Isolated: each stage against the CPU stage recomputed from the previous "
          "stage under test. Heat maps: error/bound, black 0, yellow 1, red to white above 1, "
          "magenta NaN/Inf on one side only. Previews keep each block's peak; full-size PNG and "
          "raw EXR files are beside this page.</p>";
}

// Every hypothesis tried on a failing stage, best first: the oracle run with that one change,
// and the fraction of the stage's values it brings within bound.
void write_causes(std::ostringstream& html, const parity::StageComparison& s) {
  if (s.verdict == parity::Verdict::pass) return;
  html << "<p class='cause'><b>" << escape::html(action_line(s)) << "</b><br>"
       << escape::html(cause_line(s)) << "</p>";
  if (s.causes.empty()) return;
  html << "<h3>causes tested (the oracle with one change)</h3><table><tr><th>hypothesis</th>"
          "<th>values within bound</th><th>as specified</th><th style='text-align:left'>detail"
          "</th></tr>";
  for (const parity::CauseFit& c : s.causes)
    html << "<tr><td style='text-align:left'>" << escape::html(c.description) << "</td><td>"
         << percent(c.within) << "</td><td>" << percent(c.oracle_within)
         << "</td><td style='text-align:left'>" << escape::html(c.detail) << "</td></tr>";
  html << "</table>";
}

void write_worst(std::ostringstream& html, const parity::StageComparison& s) {
  html << "<h3>worst values (largest error / bound)</h3><table><tr><th>x</th><th>y</th><th>ch</th>"
          "<th>oracle</th><th>device</th><th>|err|</th><th>bound</th><th>err/bound</th>"
          "<th style='text-align:left'>bound terms</th></tr>";
  for (const auto& w : s.worst) {
    std::string terms;
    for (const auto& t : w.terms)
      if (t.value != 0) terms += escape::html(t.name) + " = " + num(t.value) + "<br>";
    html << "<tr><td>" << w.x << "</td><td>" << w.y << "</td><td>" << "RGB"[w.channel]
         << "</td><td>" << num(w.oracle) << "</td><td>" << num(w.gl) << "</td><td>"
         << (std::isfinite(w.error) ? num(w.error) : "non-finite") << "</td><td>" << num(w.bound)
         << "</td><td>" << (std::isfinite(w.error) && w.bound > 0 ? num(w.error / w.bound) : "-")
         << "</td><td style='text-align:left'>" << terms << "</td></tr>";
  }
  html << "</table><h3>signed f16-ULP differences (device - oracle), log scale</h3>"
       << histogram_svg(s.ulp_histogram);
}

// One stage's section: the full-size files beside the page, previews, the causes, the worst
// values and the ULP histogram.
void write_stage(std::ostringstream& html, const fs::path& root, const parity::StageComparison& s,
                 const parity::StageComparison& end_to_end, const Image& captured, bool first,
                 const std::string& captured_file) {
  const bool scene_referred = s.stage != "tonemap" && s.stage != "output";
  double scale = 0;
  Image raw, heat, mask;
  ratio_images(captured, s.oracle, s.bound, raw, heat, mask);
  const Image diff = signed_diff(captured, s.oracle, scale);
  Image signed_raw(captured.width(), captured.height());
  for (std::size_t k = 0; k < signed_raw.values().size(); ++k)
    signed_raw.values()[k] = k % 4 == 3 ? 1.0f : captured.values()[k] - s.oracle.values()[k];
  const std::string base = (root / s.stage).string();
  save_exr(base + ".oracle.exr", s.oracle.cview());
  // The user's own file is linked, not copied (a float EXR is most of a report's size).
  std::string under_test = s.stage + ".device.exr";
  if (captured_file.empty()) {
    save_exr(base + ".device.exr", captured.cview());
  } else {
    std::error_code ec;
    const fs::path rel = fs::proximate(fs::absolute(captured_file, ec), fs::absolute(root, ec), ec);
    under_test = ec ? captured_file : rel.generic_string();
  }
  save_exr(base + ".diff.exr", signed_raw.cview());
  save_exr(base + ".ratio.exr", raw.cview());
  const Image d_or = display(s.oracle, scene_referred), d_gl = display(captured, scene_referred);
  save_png(base + ".oracle.png", d_or.cview());
  save_png(base + ".device.png", d_gl.cview());
  save_png(base + ".diff.png", diff.cview());
  save_png(base + ".ratio.png", heat.cview());
  save_png(base + ".mask.png", mask.cview());

  html << "<section id='stage-" << escape::html(s.stage) << "'" << (first ? " class='first'" : "")
       << "><h2>" << escape::html(s.stage) << ": <span class='" << parity::to_string(s.verdict) << "'>"
       << parity::to_string(s.verdict) << "</span>" << (first ? " (first divergent)" : "")
       << "</h2><p>" << escape::html(s.reason) << "; end to end " << parity::to_string(end_to_end.verdict)
       << ": " << escape::html(end_to_end.reason) << "</p><p class='files'>full size: <a href='"
       << escape::url(s.stage + ".oracle.exr") << "'>oracle</a>, <a href='" << escape::url(under_test)
       << "'>under test</a>, <a href='" << escape::url(s.stage + ".diff.exr") << "'>difference</a>, <a href='"
       << escape::url(s.stage + ".ratio.exr") << "'>error / bound</a> (EXR)</p>";
  write_causes(html, s);
  const std::pair<const Image*, std::string> figs[] = {
      {&d_or, "oracle (CPU from the previous stage under test)"},
      {&d_gl, "under test"},
      {&diff, "under test - oracle, full scale " + num(scale)},
      {&heat, "error / bound"},
      {&mask, "pass (green) / fail (red)"}};
  for (const auto& [img, caption] : figs)
    html << "<figure><img src='" << png_data_uri(preview(*img, img != &d_or && img != &d_gl))
         << "'><figcaption>" << escape::html(caption) << "</figcaption></figure>";
  write_worst(html, s);
  html << "</section>";
}

}  // namespace

std::string action_line(const parity::StageComparison& s) {
  if (s.verdict == parity::Verdict::pass) return "";
  std::string v = parity::to_string(s.verdict);
  const std::string head = s.stage + ": " + v + " \u2014 ";
  if (s.causes.empty()) return head + "no usual cause explains it; " + s.reason;
  const parity::CauseFit& c = s.causes.front();
  // A fitted cause's detail says what changed and by how much; a long one (fitted weights)
  // gives way to the description. A fixed change's detail (the option that declares it) follows.
  const bool short_detail = !c.detail.empty() && c.detail.size() <= 100;
  const std::string what = c.params > 0 && short_detail ? c.detail : c.description;
  std::string also;
  for (const parity::CauseFit& o : s.causes)
    if (o.as_likely) also += (also.empty() ? " (as likely: " : "; ") + o.description;
  return head + what + ", explains " + percent(c.within) +
         (c.likely() ? "" : " (a partial explanation)") +
         (c.params == 0 && short_detail ? "; " + c.detail : "") + (also.empty() ? "" : also + ")");
}

std::string cause_line(const parity::StageComparison& s) {
  if (s.causes.empty())
    return s.verdict == parity::Verdict::pass
               ? ""
               : "no usual cause explains it" + (s.residual.empty() ? "" : "; the residual: " + s.residual);
  const parity::CauseFit& c = s.causes.front();
  std::string line = (c.likely() ? "likely cause: " : "best partial explanation: ") +
                     c.description + " (brings " + percent(c.within) +
                     " of values within bound; as specified " + percent(c.oracle_within) + ")";
  if (!c.detail.empty()) line += "; " + c.detail;
  if (std::isfinite(c.low) && std::isfinite(c.high)) {
    char b[120];
    std::snprintf(b, sizeof b, " (fitted %.5g; explains from %.5g to %.5g)", c.value, c.low, c.high);
    line += b;
  }
  // Other causes that explain as much are said too: the captures cannot tell them apart.
  for (std::size_t i = 1; i < s.causes.size(); ++i) {
    const parity::CauseFit& o = s.causes[i];
    if (o.as_likely)
      line += "; as likely: " + o.description + (o.detail.empty() ? "" : " (" + o.detail + ")");
  }
  return line;
}

bool report_may_write(const std::string& filename) {
  if (filename == "index.html") return true;
  auto ends = [&filename](const std::string& tail) {
    return filename.size() > tail.size() &&
           filename.compare(filename.size() - tail.size(), tail.size(), tail) == 0;
  };
  for (const char* kind : {".oracle", ".device", ".diff", ".ratio", ".mask"})
    for (const char* ext : {".exr", ".png"})
      if (ends(std::string(kind) + ext)) return true;
  return false;
}

void write_report(const std::string& dir, const std::string& source, const std::string& renderer,
                  const Plan& plan, const StageTrace& gl, const parity::ParityResult& r,
                  const std::string& fault, const CapturedFiles& files) {
  StagedFolder staged(dir);
  write_report_files(staged.path(), source, renderer, plan, gl, r, fault, files);
  staged.publish();
}

void write_report_files(const std::string& dir, const std::string& source,
                        const std::string& renderer, const Plan& plan, const StageTrace& gl,
                        const parity::ParityResult& r, const std::string& fault,
                        const CapturedFiles& files) {
  if (!fs::is_directory(dir)) throw InputError(dir, "is not a folder");
  const fs::path root(dir);
  const std::string first = r.first_divergent_stage.value_or("");
  std::ostringstream html;
  write_head(html, source, renderer, plan, r, fault);
  write_summary(html, r);
  // Sections: the first divergent stage first, then the pipeline order.
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < r.isolated.size(); ++i)
    if (r.isolated[i].stage == first) order.push_back(i);
  for (std::size_t i = 0; i < r.isolated.size(); ++i)
    if (r.isolated[i].stage != first) order.push_back(i);
  for (std::size_t i : order) {
    const auto& s = r.isolated[i];
    const StageResult* g = gl.find(s.stage);
    const auto file = files.find(s.stage);
    if (g && !s.oracle.empty())
      write_stage(html, root, s, r.end_to_end[i], g->image, s.stage == first,
                  file == files.end() ? "" : file->second);
  }
  html << "<script>if(!location.hash&&'" << first << "')location.hash='stage-" << first
       << "';</script></body></html>\n";
  save_text((root / "index.html").string(), html.str());
}

}  // namespace bloomref::cli
