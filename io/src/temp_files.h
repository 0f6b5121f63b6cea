// Internal to the I/O module: the names of bloomref's named temporaries, their removal by a
// later run, and their removal on SIGINT, SIGTERM and SIGHUP.
//
// Outputs are written into unnamed files where the filesystem has them (output_files.cpp), so a
// process killed by any signal, SIGKILL included, leaves nothing behind. Named temporaries remain
// for the rest: filesystems without O_TMPFILE (NFS, some FUSE), the instant between linking a
// finished file to a hidden name and renaming it over the destination, and folders built before
// they are moved into place (a report). Each is named
//     .NAME.tmp-PID-N@HOST.EXT        (a folder: .NAME.tmp-PID-N@HOST)
// with HOST the host name reduced to [A-Za-z0-9_-] (so that a folder shared between machines,
// as in a Slurm array, never has one machine remove another's temporaries), and is:
//   - removed by the signal handlers below if the process is interrupted;
//   - removed by the next bloomref that writes into the same folder on the same host, once no
//     process PID exists there (remove_stale_temps), which covers SIGKILL and power loss.
#pragma once

#include <filesystem>
#include <string>

namespace bloomref::detail {

/// A hidden, unique name in `dir` for a temporary of `destination`'s (its stem and extension;
/// `folder`: no extension).
std::filesystem::path temp_name(const std::filesystem::path& dir,
                                const std::filesystem::path& destination, bool folder = false);

/// Whether `name` (a file name, no folder) is a temporary made by temp_name on this host, and
/// if so its process id.
bool parse_temp_name(const std::string& name, long& pid);

/// Removes the temporaries in `dir` (files, and folders with what they hold) that temp_name made
/// on this host for a process that no longer exists. Once per folder per process; errors are
/// ignored (another process may be removing the same ones).
void remove_stale_temps(const std::filesystem::path& dir);

/// A named temporary the signal handlers remove (a file, or a folder and the files directly in
/// it) while this object lives. The handlers for SIGINT, SIGTERM and SIGHUP are installed by
/// the first registration, where the signal's disposition is still the default; after removing
/// every registered temporary they re-raise the signal with its default action (the exit
/// status says which signal ended the process).
class TempRegistration {
 public:
  TempRegistration() = default;
  TempRegistration(const std::filesystem::path& path, bool folder);
  ~TempRegistration() { release(); }
  TempRegistration(TempRegistration&& o) noexcept : slot_(o.slot_) { o.slot_ = -1; }
  TempRegistration& operator=(TempRegistration&& o) noexcept;
  TempRegistration(const TempRegistration&) = delete;
  TempRegistration& operator=(const TempRegistration&) = delete;
  /// Stops watching (the temporary was renamed into place or removed).
  void release();

 private:
  int slot_ = -1;
};

}  // namespace bloomref::detail
