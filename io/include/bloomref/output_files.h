// bloomref — how outputs reach the disk: nothing lost, nothing left behind.
//
// The rules every writer of bloomref follows (save_image, save_text and the commands):
//   - A destination is checked before the work that fills it (require_writable_file,
//     require_writable_dir, OutputSet::add_file): a missing or read-only folder is an InputError
//     naming it (exit 2) before any computation, never after.
//   - A file is written into an unnamed file in its destination's folder (Linux O_TMPFILE) and
//     given its name only when complete (linkat through /proc/self/fd, then rename over the old
//     file). A process killed at any moment, by SIGKILL too, leaves the destination as it was
//     and no partial file. Filesystems without O_TMPFILE get a hidden named temporary instead,
//     which SIGINT, SIGTERM and SIGHUP remove, and which the next bloomref writing into that
//     folder removes once its process is gone (SIGKILL). Setting BLOOMREF_NO_TMPFILE=1 uses the
//     named temporaries everywhere (tests; filesystems whose O_TMPFILE misbehaves).
//   - A folder written as a whole (a report) is built in a hidden folder beside it and moved
//     into place when complete (StagedFolder).
//   - The outputs of one command are published all together or not at all (OutputSet): every
//     file is complete before the first is renamed into place.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/io.h"

namespace bloomref {

/// Throws InputError naming `path` (and `option`, e.g. "-o", in the message) unless a file can
/// be written there: its folder exists and is writable, `path` is not a folder, and an existing
/// file there is writable.
void require_writable_file(const std::string& path, const std::string& option);

/// The same for a folder: an existing writable folder, or a name whose parent is one.
void require_writable_dir(const std::string& path, const std::string& option);

/// One file being written: an unnamed file in the destination's folder until publish().
/// Discarded by the destructor unless published. Throws InputError naming the destination.
class PendingFile {
 public:
  explicit PendingFile(const std::string& destination);
  ~PendingFile();
  PendingFile(PendingFile&&) noexcept;
  PendingFile& operator=(PendingFile&&) noexcept;

  const std::string& destination() const;
  /// The file's descriptor, open for writing, until prepare(); -1 after.
  int fd() const;
  /// Gives the finished file a hidden name beside the destination and closes it: nothing is
  /// replaced yet. (A no-op for a named temporary, which has one from the start.)
  void prepare();
  /// Renames the prepared file over the destination.
  void commit();
  void publish() {
    prepare();
    commit();
  }

 private:
  struct State;
  std::unique_ptr<State> s_;
};

/// A folder built under a hidden name beside `destination` (created with its parents) and moved
/// into place by publish(): renamed there when no folder or an empty one is there, otherwise
/// its files are moved into the existing folder one by one (replacing files of the same names,
/// keeping the others). Removed by the destructor unless published.
class StagedFolder {
 public:
  explicit StagedFolder(const std::string& destination);
  ~StagedFolder();
  StagedFolder(StagedFolder&&) noexcept;
  StagedFolder& operator=(StagedFolder&&) noexcept;
  /// Where to write the folder's files.
  const std::string& path() const;
  const std::string& destination() const;
  void publish();

 private:
  struct State;
  std::unique_ptr<State> s_;
};

/// A private, flat temporary folder (files only) under TMPDIR or the system's: removed with what
/// it holds by the destructor, and by the handlers of SIGINT, SIGTERM and SIGHUP (then the
/// signal ends the process as it would have). For files a command makes and reads back itself.
class ScratchFolder {
 public:
  ScratchFolder();
  ~ScratchFolder();
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
  const std::filesystem::path& path() const;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

/// The outputs of one command, all or nothing. Declare every destination before the work
/// (add_file, add_folder: each checked at once, never an input, never named twice), write each
/// output when it is ready (write_image, write_text, folder), then publish() them all. Anything
/// not published is discarded by the destructor, and folders it created for outputs are removed
/// again when left empty.
class OutputSet {
 public:
  OutputSet();
  ~OutputSet();
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  /// An input no output may replace (refuse_overwrite); give inputs before outputs.
  void protect(const std::string& input);
  /// A file to write. Its folder must exist, unless it is a folder given to add_folder before.
  void add_file(const std::string& path, const std::string& option);
  /// A folder. `whole`: built whole and moved into place (StagedFolder; write into folder()).
  /// Otherwise a folder that will hold files given to add_file, created when the first is
  /// written; files already in it that are not outputs are kept.
  void add_folder(const std::string& path, const std::string& option, bool whole);

  /// Writes an output declared with add_file (by extension, as save_image).
  void write_image(const std::string& path, ConstImageView img, const ImageInfo* windows = nullptr,
                   ExrCompression compression = ExrCompression::piz);
  void write_text(const std::string& path, const std::string& text);
  /// Where to write the files of a folder declared whole.
  const std::string& folder(const std::string& path);

  /// Publishes every output written: all files are first given hidden names (nothing replaced
  /// if one fails), then renamed into place, then the whole folders moved.
  void publish();

 private:
  /// Throws unless `path` was given to add_file; makes the folder holding it, where it is one
  /// given to add_folder that does not exist yet.
  void declared_file(const std::string& path);
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace bloomref
