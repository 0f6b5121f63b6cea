// bloomref tradeoff [--size WxH] [--markdown FILE] [--svg FILE] [--json FILE]: error against run
// time. Every configuration runs the same scene; its time (median of 3 after a warm-up; GL with
// glFinish) and its error against the CPU f64 truth of the same method and parameters: largest
// and RMS display-output error, 8-bit codes differing, largest bloom error over the truth's
// bloom peak. The Pareto front (no other configuration both faster and more accurate, on the
// largest output error) is marked. The plot is log time against log error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>

#include "bloomref/error.h"
#include "escape.h"
#include "bloomref/gpu/gl_executor.h"
#include "bloomref/io.h"
#include "bloomref/scenes.h"
#include "bloomref/stages.h"
#include "commands.h"
#include "json_out.h"
#include "options.h"

namespace bloomref::cli {
namespace {

struct Config {
  std::string name;
  BloomParams params;
  bool gl = false;
  gpu::ShaderKind shaders = gpu::ShaderKind::fragment;
};

struct Point {
  std::string name;
  double ms = 0, out_max = 0, out_rms = 0, bloom_rel = 0;
  std::size_t codes = 0;
  bool front = false;
};

// Every configuration the command times: CPU blur paths, kernels, storage and precision; GL
// shader kinds, storage and kernels (with a context); mip level counts.
std::vector<Config> tradeoff_configs(bool gl) {
  std::vector<Config> configs;
  auto add = [&](std::string name, auto adjust, bool on_gl = false,
                 gpu::ShaderKind k = gpu::ShaderKind::fragment) {
    BloomParams p;
    adjust(p);
    configs.push_back({std::move(name), p, on_gl, k});
  };
  add("cpu f32 discrete9 full (reference loop)", [](BloomParams& p) {
    p.plan = PlanMode::full;
    p.blur = BlurImpl::reference;
  });
  add("cpu f32 discrete9 full (fast exact)", [](BloomParams& p) { p.plan = PlanMode::full; });
  add("cpu f32 discrete9 adaptive (fast exact)", [](BloomParams&) {});
  add("cpu f32 approx full (fast approximate, fused)", [](BloomParams& p) {
    p.plan = PlanMode::full;
    p.blur = BlurImpl::approx;
  });
  add("cpu f32 approx adaptive (fast approximate)",
      [](BloomParams& p) { p.blur = BlurImpl::approx; });
  add("cpu f32 linear5", [](BloomParams& p) { p.kernel = KernelName::linear5; });
  add("cpu f32 discrete9 f16", [](BloomParams& p) { p.storage = Storage::f16; });
  add("cpu f64 discrete9 (truth)", [](BloomParams& p) { p.precision = Precision::f64; });
  if (gl)
    for (gpu::ShaderKind k : {gpu::ShaderKind::fragment, gpu::ShaderKind::compute})
      for (Storage st : {Storage::f32, Storage::f16})
        for (KernelName kn : {KernelName::discrete9, KernelName::linear5})
          add(
              "gl " + gpu::to_string(k) + " " + to_string(st) + " " + to_string(kn),
              [=](BloomParams& p) {
                p.storage = st;
                p.kernel = kn;
              },
              true, k);
  for (int levels : {3, 5, 7}) {
    add("cpu f32 mip " + std::to_string(levels) + " levels", [=](BloomParams& p) {
      p.method = Method::mip;
      p.levels = levels;
    });
    if (gl)
      add(
          "gl fragment f32 mip " + std::to_string(levels) + " levels",
          [=](BloomParams& p) {
            p.method = Method::mip;
            p.levels = levels;
          },
          true);
  }
  return configs;
}

// Largest and RMS display-output error against the f64 truth, and 8-bit codes differing.
void output_errors(const Image& o, const ImageF64& o64, Point& pt) {
  double sum2 = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < o.values().size(); ++i) {
    if (i % 4 == 3) continue;
    const double d = std::fabs(o.values()[i] - o64.values()[i]);
    if (!std::isfinite(d)) continue;
    pt.out_max = std::max(pt.out_max, d);
    sum2 += d * d;
    ++n;
    pt.codes += quantize_8bit(o.values()[i]) != quantize_8bit(float(o64.values()[i]));
  }
  pt.out_rms = std::sqrt(sum2 / std::max<std::size_t>(n, 1));
}

// Largest bloom error over the truth's bloom peak.
double bloom_relative_error(const Image& b, const Image& b64) {
  double peak = 0, diff = 0;
  for (std::size_t i = 0; i < b.values().size(); ++i) {
    if (i % 4 == 3) continue;
    peak = std::max(peak, double(std::fabs(b64.values()[i])));
    diff = std::max(diff, double(std::fabs(b.values()[i] - b64.values()[i])));
  }
  return peak > 0 ? diff / peak : diff;
}

// One configuration: median of 3 timed runs after a warm-up, errors against the CPU f64 truth of
// the same method and parameters (exact taps, discrete9, no storage rounding).
Point measure(const Config& c, const Image& scene, gpu::GlContext* ctx) {
  BloomParams tp = c.params;
  tp.precision = Precision::f64;
  tp.storage = Storage::f32;
  tp.kernel = KernelName::discrete9;
  tp.plan = PlanMode::full;
  const Plan truth_plan = make_plan(tp, scene.cview());
  const StageTrace truth = execute(truth_plan, scene.cview(), {true});
  Plan plan;  // each run makes its plan again (its scan is timed, "plan")
  auto run = [&](bool keep) {
    plan = make_plan(c.params, scene.cview());
    if (!c.gl) return execute(plan, scene.cview(), {keep});
    gpu::GlOptions go;
    go.shaders = c.shaders;
    go.keep_all = keep;
    return gpu::execute_gl(*ctx, plan, scene.cview(), go);
  };
  run(false);  // warm-up
  std::vector<double> t;
  for (int i = 0; i < 3; ++i) t.push_back(run(false).total_ms);
  std::sort(t.begin(), t.end());
  const StageTrace r = run(true);
  Point pt{c.name, t[1]};
  output_errors(r.final_image(), *truth.output_f64, pt);
  pt.bloom_rel = bloom_relative_error(r.find(bloom_stage_name(plan))->image,
                                      truth.find(bloom_stage_name(truth_plan))->image);
  return pt;
}

// Marks the Pareto front: no other point both faster and more accurate (largest output error).
void mark_front(std::vector<Point>& points) {
  for (Point& p : points) {
    p.front = true;
    for (const Point& q : points)
      if (&q != &p && q.ms <= p.ms && q.out_max <= p.out_max &&
          (q.ms < p.ms || q.out_max < p.out_max))
        p.front = false;
  }
}

std::string markdown_table(const std::vector<Point>& points, const std::string& size,
                           const std::string& scene, const std::string& renderer) {
  std::ostringstream md;
  md << "# bloomref: error against run time\n\nGenerated by `scripts/tradeoff-report` (`bloomref "
        "tradeoff --size "
     << size << "`), scene " << scene << ", " << renderer << ". Time: median of 3 after a "
     << "warm-up, I/O excluded (GL: glFinish after every stage). Error against the CPU f64 "
        "truth of the same method and level count (exact taps, discrete9, no storage "
        "rounding): the mip rows measure precision, not the difference between methods. "
        "Pareto front (no configuration both faster and more accurate on the largest output "
        "error): **bold**.\n\n![error against run time](tradeoff.png)\n\n"
        "| configuration | ms | output max abs | output RMS | 8-bit codes differing | bloom max "
        "rel |\n"
        "|---|---|---|---|---|---|\n";
  char buf[256];
  for (const Point& p : points) {
    std::snprintf(buf, sizeof buf, "| %s%s%s | %.1f | %.2e | %.2e | %zu | %.2e |\n",
                  p.front ? "**" : "", p.name.c_str(), p.front ? "**" : "", p.ms, p.out_max,
                  p.out_rms, p.codes, p.bloom_rel);
    md << buf;
  }
  return md.str();
}

// The plot: log10 time (x) against log10 max output error (y); 0 errors drawn at 1e-9.
std::string svg_plot(const std::vector<Point>& points) {
  std::ostringstream svg;
  const double W = 900, H = 560, L = 80, R = 260, T = 30, B = 60;
  double tmin = 1e30, tmax = 0;
  for (const Point& p : points) tmin = std::min(tmin, p.ms), tmax = std::max(tmax, p.ms);
  const double lx0 = std::floor(std::log10(tmin)), lx1 = std::ceil(std::log10(tmax)) + 1e-9;
  const double ly0 = -9, ly1 = 0;
  auto X = [&](double ms) { return L + (std::log10(ms) - lx0) / (lx1 - lx0) * (W - L - R); };
  auto Y = [&](double e) {
    return T + (ly1 - std::log10(std::max(e, 1e-9))) / (ly1 - ly0) * (H - T - B);
  };
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
      << "' font-family='sans-serif' font-size='11'><rect width='100%' height='100%' "
         "fill='white'/>";
  for (int e = int(ly0); e <= int(ly1); ++e)
    svg << "<line x1='" << L << "' x2='" << W - R << "' y1='" << Y(std::pow(10, e)) << "' y2='"
        << Y(std::pow(10, e)) << "' stroke='#eee'/><text x='" << L - 8 << "' y='"
        << Y(std::pow(10, e)) + 4 << "' text-anchor='end'>1e" << e << "</text>";
  for (int e = int(lx0); e <= int(std::ceil(lx1)); ++e)
    svg << "<line y1='" << T << "' y2='" << H - B << "' x1='" << X(std::pow(10, e)) << "' x2='"
        << X(std::pow(10, e)) << "' stroke='#eee'/><text y='" << H - B + 16 << "' x='"
        << X(std::pow(10, e)) << "' text-anchor='middle'>" << std::pow(10, e) << " ms</text>";
  svg << "<text x='" << (W - R + L) / 2 << "' y='" << H - 15
      << "' text-anchor='middle'>run time (log)</text><text transform='translate(18," << H / 2
      << ") rotate(-90)' text-anchor='middle'>largest display-output error vs f64 (log; 0 at "
         "1e-9)</text>";
  std::vector<const Point*> front;
  for (const Point& p : points)
    if (p.front) front.push_back(&p);
  std::sort(front.begin(), front.end(),
            [](const Point* a, const Point* b) { return a->ms < b->ms; });
  svg << "<polyline fill='none' stroke='#c00' stroke-dasharray='4 3' points='";
  for (const Point* p : front) svg << X(p->ms) << "," << Y(p->out_max) << " ";
  svg << "'/>";
  int i = 0;
  for (const Point& p : points) {
    const double x = X(p.ms), y = Y(p.out_max);
    ++i;
    svg << "<circle cx='" << x << "' cy='" << y << "' r='5' fill='" << (p.front ? "#c00" : "#36c")
        << "'/><text x='" << x + 7 << "' y='" << y - 4 << "' font-size='9'>" << i << "</text>"
        << "<text x='" << W - R + 12 << "' y='" << T + 14 * i << "' fill='"
        << (p.front ? "#c00" : "#333") << "'>" << i << ". " << p.name << "</text>";
  }
  svg << "</svg>\n";
  return svg.str();
}

nlohmann::ordered_json points_json(const std::vector<Point>& points) {
  nlohmann::ordered_json j = nlohmann::ordered_json::array();
  for (const Point& p : points)
    j.push_back({{"configuration", p.name},
                 {"ms", p.ms},
                 {"output_max_abs", p.out_max},
                 {"output_rms", p.out_rms},
                 {"codes_differing", p.codes},
                 {"bloom_max_rel", p.bloom_rel},
                 {"pareto", p.front}});
  return j;
}

}  // namespace

std::function<int()> add_tradeoff(CLI::App& app) {
  struct Args {
    std::string size = "1920x1080", markdown, svg, json, scene = "demo";
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = app.add_subcommand("tradeoff", "error against run time over configurations");
  sub->add_option("--size", a->size, "WxH of the scene")->capture_default_str();
  sub->add_option("--scene", a->scene, "built-in scene")->capture_default_str();
  sub->add_option("--markdown", a->markdown, "write the table as Markdown");
  sub->add_option("--svg", a->svg, "write the plot as SVG");
  sub->add_option("--json", a->json, "write the points as JSON");
  return [a, sub]() -> int {
    if (!sub->parsed()) return -1;
    int w = 0, h = 0;
    parse_size(a->size, w, h);
    const Image scene = make_scene(a->scene, w, h);
    std::unique_ptr<gpu::GlContext> ctx;
    try {
      ctx = gpu::GlContext::create();
    } catch (const gpu::GlUnavailable&) {
    }
    std::vector<Point> points;
    for (const Config& c : tradeoff_configs(ctx != nullptr)) {
      points.push_back(measure(c, scene, ctx.get()));
      const Point& pt = points.back();
      std::fprintf(stderr, "%-34s %9.1f ms  out max %.2e\n", pt.name.c_str(), pt.ms, pt.out_max);
    }
    mark_front(points);
    const std::string md = markdown_table(points, a->size, a->scene,
                                          ctx ? ctx->info().renderer : std::string("no GL"));
    if (!a->markdown.empty()) save_text(a->markdown, md);
    if (!a->svg.empty()) save_text(a->svg, svg_plot(points));
    if (!a->json.empty()) save_text(a->json, escape::json_text(points_json(points)) + "\n");
    if (a->markdown.empty()) std::fputs(md.c_str(), stdout);
    return 0;
  };
}

}  // namespace bloomref::cli
