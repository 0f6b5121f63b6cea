// Outputs written whole or not at all (output_files.h); temporaries' names and their removal
// in temp_files.cpp.
#include "bloomref/output_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <system_error>

#include "bloomref/error.h"
#include "io_internal.h"
#include "temp_files.h"

namespace fs = std::filesystem;

namespace bloomref {
namespace {

std::string errno_text(int e) { return std::strerror(e); }

fs::path folder_of(const fs::path& file) {
  fs::path dir = file.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

// Whether to write into unnamed files: not when BLOOMREF_NO_TMPFILE is set, nor without
// /proc/self/fd (linkat names an unnamed file through it; AT_EMPTY_PATH would need
// CAP_DAC_READ_SEARCH).
bool unnamed_files_wanted() {
  static const bool wanted = [] {
    const char* env = std::getenv("BLOOMREF_NO_TMPFILE");
    if (env && *env && std::strcmp(env, "0") != 0) return false;
    return ::access("/proc/self/fd", X_OK) == 0;
  }();
  return wanted;
}

// The same path however it is spelled, whether it exists yet or not (weakly_canonical of a
// relative path whose first component does not exist stays relative: made absolute first).
fs::path key_of(const std::string& path) {
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec);
  fs::path k = fs::weakly_canonical(ec ? fs::path(path) : abs, ec);
  if (ec) k = abs.lexically_normal();
  // A folder named with a trailing separator ("st.0001/") is the same destination without it.
  if (!k.has_filename() && k.has_parent_path()) k = k.parent_path();
  return k;
}

}  // namespace

void require_writable_file(const std::string& path, const std::string& option) {
  const fs::path p(path);
  const fs::path dir = folder_of(p);
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw InputError(path, "cannot be written (" + option + "): the folder " + dir.string() +
                               " does not exist");
  if (fs::is_directory(p, ec))
    throw InputError(path, "is a folder; " + option + " needs a file name");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw InputError(path, "cannot be written (" + option + "): the folder " + dir.string() +
                               " is not writable");
  if (fs::exists(p, ec) && ::access(p.c_str(), W_OK) != 0)
    throw InputError(path, "cannot be written (" + option + "): not writable");
}

void require_writable_dir(const std::string& path, const std::string& option) {
  const fs::path p(path);
  std::error_code ec;
  if (fs::exists(p, ec)) {
    if (!fs::is_directory(p, ec))
      throw InputError(path, "exists and is not a folder (" + option + ")");
    if (::access(p.c_str(), W_OK | X_OK) != 0)
      throw InputError(path, "is not writable (" + option + ")");
    return;
  }
  fs::path normal = p.lexically_normal();  // "st.0001/" names the folder st.0001
  if (!normal.has_filename() && normal.has_parent_path()) normal = normal.parent_path();
  const fs::path parent = folder_of(normal);
  if (!fs::is_directory(parent, ec) || ::access(parent.c_str(), W_OK | X_OK) != 0)
    throw InputError(path, "cannot be created (" + option + "): " + parent.string() +
                               " is not a writable folder");
}

// --- PendingFile -----------------------------------------------------------------------------

struct PendingFile::State {
  std::string dest;
  fs::path dir;
  int fd = -1;
  fs::path named;  // the hidden name: a named temporary's from the start, or given by prepare()
  detail::TempRegistration watched;
  bool committed = false;

  ~State() {
    if (fd >= 0) ::close(fd);
    if (!committed && !named.empty()) ::unlink(named.c_str());
  }
};

PendingFile::PendingFile(const std::string& destination) : s_(std::make_unique<State>()) {
  s_->dest = destination;
  const fs::path target(destination);
  s_->dir = folder_of(target);
  std::error_code ec;
  if (!fs::is_directory(s_->dir, ec))
    throw InputError(destination, "the output folder " + s_->dir.string() + " does not exist");
  if (fs::is_directory(target, ec)) throw InputError(destination, "is a folder, not a file");
  detail::remove_stale_temps(s_->dir);
  if (unnamed_files_wanted()) {
    s_->fd = ::open(s_->dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
    if (s_->fd >= 0) return;
    // EOPNOTSUPP: the filesystem has none; EISDIR, EINVAL: the kernel or C library has none.
    if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL)
      throw InputError(destination, "cannot write in the folder " + s_->dir.string() + ": " +
                                        errno_text(errno));
  }
  s_->named = detail::temp_name(s_->dir, target);
  s_->watched = detail::TempRegistration(s_->named, false);
  s_->fd = ::open(s_->named.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (s_->fd < 0) {
    const int e = errno;
    s_->named.clear();  // nothing made
    throw InputError(destination, "cannot write in the folder " + s_->dir.string() + ": " +
                                      errno_text(e));
  }
}

PendingFile::~PendingFile() = default;
PendingFile::PendingFile(PendingFile&&) noexcept = default;
PendingFile& PendingFile::operator=(PendingFile&&) noexcept = default;

const std::string& PendingFile::destination() const { return s_->dest; }
int PendingFile::fd() const { return s_->fd; }

void PendingFile::prepare() {
  if (s_->fd < 0) return;
  if (s_->named.empty()) {
    const fs::path named = detail::temp_name(s_->dir, s_->dest);
    s_->watched = detail::TempRegistration(named, false);
    const std::string proc = "/proc/self/fd/" + std::to_string(s_->fd);
    if (::linkat(AT_FDCWD, proc.c_str(), AT_FDCWD, named.c_str(), AT_SYMLINK_FOLLOW) != 0)
      throw InputError(s_->dest, "cannot give the finished file a name in " + s_->dir.string() +
                                     ": " + errno_text(errno));
    s_->named = named;
  }
  const int fd = s_->fd;
  s_->fd = -1;
  if (::close(fd) != 0)  // NFS reports a failed write here
    throw InputError(s_->dest, "cannot write: " + errno_text(errno));
}

void PendingFile::commit() {
  prepare();
  if (s_->committed) return;
  if (::rename(s_->named.c_str(), s_->dest.c_str()) != 0)
    throw InputError(s_->dest,
                     "cannot move the finished file into place: " + errno_text(errno));
  s_->committed = true;
  s_->watched.release();
}

// --- StagedFolder ----------------------------------------------------------------------------

struct ScratchFolder::State {
  fs::path path;
  detail::TempRegistration watched;
};

ScratchFolder::ScratchFolder() : s_(std::make_unique<State>()) {
  static std::atomic<int> counter{0};
  const char* tmp = std::getenv("TMPDIR");
  const fs::path base = tmp && *tmp ? fs::path(tmp) : fs::temp_directory_path();
  s_->path = base / ("bloomref-scratch-" + std::to_string(::getpid()) + "-" +
                     std::to_string(counter++));
  s_->watched = detail::TempRegistration(s_->path, true);  // before it exists
  std::error_code ec;
  fs::remove_all(s_->path, ec);
  if (!fs::create_directories(s_->path, ec) || ec)
    throw InputError(s_->path.string(), "cannot make a temporary folder: " + ec.message());
}

ScratchFolder::~ScratchFolder() {
  std::error_code ec;
  fs::remove_all(s_->path, ec);
}

const fs::path& ScratchFolder::path() const { return s_->path; }

struct StagedFolder::State {
  std::string dest, path;
  detail::TempRegistration watched;
  bool published = false;

  ~State() {
    if (published || path.empty()) return;
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

StagedFolder::StagedFolder(const std::string& destination) : s_(std::make_unique<State>()) {
  s_->dest = destination;
  const fs::path target = fs::path(destination).lexically_normal();
  const fs::path name = target.filename().empty() ? target.parent_path() : target;
  const fs::path parent = folder_of(name);
  std::error_code ec;
  if (fs::exists(name, ec) && !fs::is_directory(name, ec))
    throw InputError(destination, "exists and is not a folder");
  fs::create_directories(parent, ec);
  if (ec) throw InputError(destination, "cannot create the folder " + parent.string() + ": " +
                                            ec.message());
  detail::remove_stale_temps(parent);
  const fs::path tmp = detail::temp_name(parent, name, /*folder=*/true);
  s_->watched = detail::TempRegistration(tmp, true);
  if (!fs::create_directory(tmp, ec) || ec)
    throw InputError(destination, "cannot create a folder in " + parent.string() + ": " +
                                      (ec ? ec.message() : std::string("it exists")));
  s_->path = tmp.string();
}

StagedFolder::~StagedFolder() = default;
StagedFolder::StagedFolder(StagedFolder&&) noexcept = default;
StagedFolder& StagedFolder::operator=(StagedFolder&&) noexcept = default;

const std::string& StagedFolder::path() const { return s_->path; }
const std::string& StagedFolder::destination() const { return s_->dest; }

void StagedFolder::publish() {
  if (s_->published) return;
  const fs::path dest = fs::path(s_->dest).lexically_normal();
  std::error_code ec;
  // An empty folder in the way is replaced by rename(2); a folder holding other files keeps
  // them (a report written into a folder of the user's).
  if (!fs::exists(dest, ec) || fs::is_empty(dest, ec)) {
    if (::rename(s_->path.c_str(), dest.c_str()) == 0) {
      s_->published = true;
      s_->watched.release();
      return;
    }
    if (errno != ENOTEMPTY && errno != EEXIST)
      throw InputError(s_->dest, "cannot move the finished folder into place: " + errno_text(errno));
  }
  if (!fs::is_directory(dest, ec)) throw InputError(s_->dest, "exists and is not a folder");
  for (const auto& e : fs::directory_iterator(s_->path, ec)) {
    const fs::path to = dest / e.path().filename();
    if (::rename(e.path().c_str(), to.c_str()) != 0)
      throw InputError(to.string(), "cannot move the finished file into place: " + errno_text(errno));
  }
  if (ec) throw InputError(s_->dest, "cannot read the finished folder: " + ec.message());
  fs::remove(s_->path, ec);
  s_->published = true;
  s_->watched.release();
}

// --- OutputSet -------------------------------------------------------------------------------

namespace {

// Pending files kept open (unnamed) at once; beyond it each is given its hidden name as soon as
// it is written (a named temporary until publish), so that a run writing thousands of stages
// stays well within the process's descriptor limit.
constexpr int kMaxOpenPending = 256;

}  // namespace

struct OutputSet::State {
  struct Folder {
    std::string path;
    fs::path key;
    bool whole = false;
    std::unique_ptr<StagedFolder> staged;  // whole
    bool created = false;                  // not whole: made by this set
  };
  std::vector<std::string> inputs;
  std::set<fs::path> declared;  // every destination (files and folders), canonical
  std::set<fs::path> declared_files;
  std::vector<Folder> folders;
  std::vector<PendingFile> written;
  int open = 0;

  Folder* folder_holding(const fs::path& file_key) {
    for (Folder& f : folders)
      if (!f.whole && f.key == file_key.parent_path()) return &f;
    return nullptr;
  }

  ~State() {
    written.clear();
    for (Folder& f : folders) {
      std::error_code ec;
      if (f.created) fs::remove(f.path, ec);  // only when left empty
    }
  }
};

OutputSet::OutputSet() : s_(std::make_unique<State>()) {}
OutputSet::~OutputSet() = default;

void OutputSet::protect(const std::string& input) {
  if (!input.empty()) s_->inputs.push_back(input);
}

void OutputSet::add_file(const std::string& path, const std::string& option) {
  for (const std::string& in : s_->inputs) refuse_overwrite(path, in);
  const fs::path key = key_of(path);
  if (!s_->declared.insert(key).second) throw InputError(path, "is named twice as an output");
  s_->declared_files.insert(key);
  if (s_->folder_holding(key)) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) throw InputError(path, "is a folder; " + option + " needs a file name");
    return;  // its folder was checked by add_folder, and may not exist yet
  }
  require_writable_file(path, option);
}

void OutputSet::add_folder(const std::string& path, const std::string& option, bool whole) {
  for (const std::string& in : s_->inputs) refuse_overwrite(path, in);
  const fs::path key = key_of(path);
  if (!s_->declared.insert(key).second) throw InputError(path, "is named twice as an output");
  require_writable_dir(path, option);
  State::Folder f;
  f.path = path;
  f.key = key;
  f.whole = whole;
  s_->folders.push_back(std::move(f));
}

void OutputSet::declared_file(const std::string& path) {
  const fs::path key = key_of(path);
  if (!s_->declared_files.count(key))
    throw std::logic_error("OutputSet: " + path + " was not declared with add_file");
  if (State::Folder* f = s_->folder_holding(key)) {  // made when its first file is written
    std::error_code ec;
    if (!fs::is_directory(f->path, ec)) {
      f->created = fs::create_directories(f->path, ec);
      if (ec) throw InputError(f->path, "cannot create the folder: " + ec.message());
    }
  }
}

void OutputSet::write_image(const std::string& path, ConstImageView img,
                            const ImageInfo* windows, ExrCompression compression) {
  declared_file(path);
  PendingFile file(path);
  detail::write_image_pending(file, img, windows, compression);
  if (++s_->open > kMaxOpenPending) file.prepare();
  s_->written.push_back(std::move(file));
}

void OutputSet::write_text(const std::string& path, const std::string& text) {
  declared_file(path);
  PendingFile file(path);
  detail::write_pending(file, [&](std::FILE* f) {
    if (std::fwrite(text.data(), 1, text.size(), f) != text.size())
      throw InputError(path, "cannot write: " + errno_text(errno));
  });
  if (++s_->open > kMaxOpenPending) file.prepare();
  s_->written.push_back(std::move(file));
}

const std::string& OutputSet::folder(const std::string& path) {
  const fs::path key = key_of(path);
  for (State::Folder& f : s_->folders)
    if (f.whole && f.key == key) {
      if (!f.staged) f.staged = std::make_unique<StagedFolder>(f.path);
      return f.staged->path();
    }
  throw std::logic_error("OutputSet: " + path + " was not declared with add_folder(whole)");
}

void OutputSet::publish() {
  for (PendingFile& f : s_->written) f.prepare();
  for (PendingFile& f : s_->written) f.commit();
  for (State::Folder& f : s_->folders) {
    if (f.staged) f.staged->publish();
    f.created = false;  // published: kept
  }
}

}  // namespace bloomref
