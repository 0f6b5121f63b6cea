// libFuzzer target: the writers of check's results (cli/check/output.h, cli/results.h) and the
// escapers they share (cli/escape.h). The input is split at NUL bytes into the fields a user
// controls: item id, scene, stage folder, error, the four device keys, a stage's reason, a
// cause's description and an expectation's reason. Findings: a crash, an exception, and any escaped field that breaks
// its language's rules -- XML (no markup character, every '&' a reference, no character XML 1.0
// forbids), HTML (no markup or quote), URL (only unreserved bytes and %XX), a Markdown cell (one
// line, every '|' escaped), JSON (parses back) -- or a document that is not valid UTF-8.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "check/output.h"
#include "escape.h"
#include "results.h"

namespace esc = bloomref::escape;
using namespace bloomref;

namespace {

bool valid_utf8(const std::string& s) { return esc::utf8(s) == s; }

void require(bool ok) {
  if (!ok) std::abort();
}

void check_xml(const std::string& e) {
  require(valid_utf8(e));
  for (std::size_t i = 0; i < e.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(e[i]);
    require(c != '<' && c != '>' && c != '"' && c != '\'');
    require(c >= 0x20);  // tab, newline, carriage return come as references
    if (c == '&') {
      const std::size_t semi = e.find(';', i);
      require(semi != std::string::npos);
      const std::string ref = e.substr(i, semi - i + 1);
      require(ref == "&amp;" || ref == "&lt;" || ref == "&gt;" || ref == "&quot;" ||
              ref == "&apos;" || ref == "&#9;" || ref == "&#10;" || ref == "&#13;");
    }
  }
  require(e.find("\xEF\xBF\xBE") == std::string::npos && e.find("\xEF\xBF\xBF") == std::string::npos);
}

void check_html(const std::string& e) {
  require(valid_utf8(e));
  for (unsigned char c : e) require(c != '<' && c != '>' && c != '"' && c != '\'' && (c >= 0x20 || c == '\t' || c == '\n'));
}

void check_url(const std::string& e) {
  for (std::size_t i = 0; i < e.size(); ++i) {
    const char c = e[i];
    const bool plain = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                       c == '-' || c == '.' || c == '_' || c == '~' || c == '/' || c == '%';
    require(plain);
  }
  require(e.rfind("//", 0) != 0);
}

void check_markdown(const std::string& e) {
  require(valid_utf8(e));
  for (std::size_t i = 0; i < e.size(); ++i) {
    require(e[i] != '\n' && e[i] != '\r');
    if (e[i] == '|') {
      std::size_t slashes = 0;
      for (std::size_t k = i; k > 0 && e[k - 1] == '\\'; --k) ++slashes;
      require(slashes % 2 == 1);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> f;
  for (std::size_t a = 0;;) {
    const std::size_t b = text.find('\0', a);
    f.push_back(text.substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  f.resize(11);
  for (const std::string& s : f) {
    check_xml(esc::xml(s));
    check_html(esc::html(s));
    check_url(esc::url(s));
    check_markdown(esc::markdown_cell(s));
    const std::string code = esc::markdown_code(s);
    require(code.size() >= 2 && code.find('`', 1) == code.size() - 1);
    const nlohmann::ordered_json back = nlohmann::ordered_json::parse(esc::json_text(s));
    require(back.get<std::string>() == esc::utf8(s));
  }

  cli::CheckRun run;
  run.verdict = "FAIL";
  run.exit_code = 1;
  run.device = {f[4], f[5], f[6], f[7]};
  run.report_dir = "rep";
  cli::Expectation expectation;
  expectation.reason = f[10];
  cli::ItemResult r;
  r.id = f[0];
  r.source = f[1];
  r.stages_from = f[2];
  r.verdict = "FAIL";
  parity::StageComparison s;
  s.stage = "blur.1";
  s.verdict = parity::Verdict::fail;
  s.reason = f[8];
  parity::CauseFit cause;
  cause.id = "wrong-weights";
  cause.description = f[9];
  cause.detail = f[9];
  s.causes.push_back(cause);
  r.parity.isolated = {s, s};
  r.parity.end_to_end = {s, s};
  r.parity.first_divergent_stage = "blur.1";
  r.outcomes = {{"fail", std::nullopt}, {"expected-fail", expectation}};
  r.file_of["blur.1"] = f[2] + "/blur.1.exr";
  run.items.push_back(r);
  cli::ItemResult e;
  e.id = f[0] + "-error";
  e.error = f[3];
  e.verdict = "ERROR";
  run.items.push_back(e);

  const nlohmann::ordered_json doc = cli::check_json(run);
  const std::string junit = results::junit(doc);
  require(valid_utf8(junit));
  for (unsigned char c : junit) require(c >= 0x20 || c == '\n');
  const std::string md = results::markdown(doc);
  require(valid_utf8(md));
  (void)results::console(doc);  // the console prints names as they are
  const std::string json = esc::json_text(doc);
  (void)nlohmann::ordered_json::parse(json);
  return 0;
}
