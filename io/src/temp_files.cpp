#include "temp_files.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>
#include <system_error>

namespace fs = std::filesystem;

namespace bloomref::detail {
namespace {

// The host name as it appears in temporaries' names: [A-Za-z0-9_-] only (no '.', which would
// read as the start of the extension), at most 40 characters.
const std::string& host_tag() {
  static const std::string tag = [] {
    char buf[256] = {};
    if (::gethostname(buf, sizeof buf - 1) != 0 || !buf[0]) std::strcpy(buf, "localhost");
    std::string t;
    for (const char* c = buf; *c && t.size() < 40; ++c)
      t += (std::isalnum(static_cast<unsigned char>(*c)) || *c == '-') ? *c : '_';
    return t;
  }();
  return tag;
}

bool all_digits(const std::string& s) {
  return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

// --- what the signal handlers remove --------------------------------------------------------
//
// Registered paths are heap strings reached through atomic pointers: the handler reads each
// pointer once and uses only async-signal-safe calls (unlink, open, getdents64, unlinkat, rmdir,
// sigaction, raise). The first character says what the path is ('f' a file, 'd' a folder).
constexpr int kSlots = 4096;
std::array<std::atomic<char*>, kSlots> g_slots{};

// A folder and the entries directly in it (the temporaries' folders are flat: a report's).
void remove_flat_folder(const char* path) {
  const int dfd = ::open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    alignas(8) char buf[4096];
    for (;;) {
      const long n = ::syscall(SYS_getdents64, dfd, buf, sizeof buf);
      if (n <= 0) break;
      for (long off = 0; off < n;) {
        // struct linux_dirent64: d_ino (8), d_off (8), d_reclen (2), d_type (1), d_name.
        unsigned short reclen;
        std::memcpy(&reclen, buf + off + 16, sizeof reclen);
        const char* name = buf + off + 19;
        if (!(name[0] == '.' && (name[1] == 0 || (name[1] == '.' && name[2] == 0))))
          ::unlinkat(dfd, name, 0);
        off += reclen;
      }
    }
    ::close(dfd);
  }
  ::rmdir(path);
}

void on_signal(int sig) {
  const int saved = errno;
  for (auto& slot : g_slots) {
    const char* p = slot.load(std::memory_order_acquire);
    if (!p) continue;
    if (p[0] == 'd') remove_flat_folder(p + 1);
    else ::unlink(p + 1);
  }
  errno = saved;
  // SA_RESETHAND restored the default action; the signal is blocked until this returns, then
  // ends the process as it would have without bloomref's handler.
  ::raise(sig);
}

void install_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction old {};
      if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler != SIG_DFL) continue;  // nohup
      struct sigaction sa {};
      sa.sa_handler = on_signal;
      sigemptyset(&sa.sa_mask);
      sa.sa_flags = SA_RESETHAND;
      ::sigaction(sig, &sa, nullptr);
    }
  });
}

}  // namespace

fs::path temp_name(const fs::path& dir, const fs::path& destination, bool folder) {
  static std::atomic<unsigned> serial{0};
  const std::string stem = folder ? destination.filename().string() : destination.stem().string();
  return dir / ("." + stem + ".tmp-" + std::to_string(::getpid()) + "-" +
                std::to_string(serial++) + "@" + host_tag() +
                (folder ? std::string() : destination.extension().string()));
}

bool parse_temp_name(const std::string& name, long& pid) {
  if (name.empty() || name[0] != '.') return false;
  const std::size_t at = name.rfind('@');
  const std::size_t tmp = name.rfind(".tmp-", at);
  if (at == std::string::npos || tmp == std::string::npos || tmp == 0) return false;
  const std::size_t dash = name.find('-', tmp + 5);
  if (dash == std::string::npos || dash > at) return false;
  const std::string p = name.substr(tmp + 5, dash - tmp - 5), n = name.substr(dash + 1, at - dash - 1);
  const std::size_t end = name.find('.', at);
  const std::string host = name.substr(at + 1, end == std::string::npos ? end : end - at - 1);
  if (!all_digits(p) || !all_digits(n) || p.size() > 9 || host != host_tag()) return false;
  pid = std::stol(p);
  return pid > 0;
}

void remove_stale_temps(const fs::path& dir) {
  static std::mutex m;
  static std::set<fs::path> done;
  std::error_code ec;
  const fs::path key = fs::weakly_canonical(dir, ec);
  {
    std::lock_guard<std::mutex> lock(m);
    if (!done.insert(ec ? dir : key).second) return;
  }
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    long pid = 0;
    if (!parse_temp_name(it->path().filename().string(), pid) || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours)
    std::error_code rm;
    fs::remove_all(it->path(), rm);
  }
}

TempRegistration::TempRegistration(const fs::path& path, bool folder) {
  install_handlers();
  const std::string s = (folder ? "d" : "f") + path.string();
  char* copy = ::strdup(s.c_str());
  if (!copy) throw std::bad_alloc();
  for (int i = 0; i < kSlots; ++i) {
    char* expected = nullptr;
    if (g_slots[i].compare_exchange_strong(expected, copy, std::memory_order_acq_rel)) {
      slot_ = i;
      return;
    }
  }
  std::free(copy);  // more than kSlots temporaries at once: this one is left to the next run
}

TempRegistration& TempRegistration::operator=(TempRegistration&& o) noexcept {
  if (this != &o) {
    release();
    slot_ = o.slot_;
    o.slot_ = -1;
  }
  return *this;
}

void TempRegistration::release() {
  if (slot_ < 0) return;
  std::free(g_slots[slot_].exchange(nullptr, std::memory_order_acq_rel));
  slot_ = -1;
}

}  // namespace bloomref::detail
