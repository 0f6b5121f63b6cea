// Helpers shared by the test binaries: the corpus (BLOOMREF_CORPUS), the inputs of the "on
// scenes and corpus" tests, bit-level image comparisons, the instruction sets this CPU has,
// temporary folders and files, and running the bloomref command as a separate process.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "bloomref/engine/fast_stages.h"
#include "bloomref/image.h"
#include "bloomref/params.h"

namespace bloomref::test {

namespace fs = std::filesystem;

/// The corpus folder (../shared/data/hdr, README.md there) from BLOOMREF_CORPUS, or "" when
/// unset, as an absolute path. A relative value is tried from the working folder, then from the
/// repository root; one that names no folder throws (a test must not pass by reading nothing).
std::string corpus_dir();

/// The path of `name` in the repository's data/ folder (data/README.md).
std::string data_path(const std::string& name);

/// Paths of every .exr and .hdr image in the corpus folder (sorted); empty when BLOOMREF_CORPUS
/// is unset.
std::vector<std::string> corpus_files();

/// Every built-in scene at its own size, then every corpus image (named by file name), then
/// `extra` -- the inputs of the "on scenes and corpus" tests.
std::vector<std::pair<std::string, Image>> scenes_and_corpus(
    std::vector<std::pair<std::string, Image>> extra = {});

/// The display output of a CPU run with these parameters.
Image run_output(const Image& scene, const BloomParams& p);

/// Every stage of a CPU run of `p` with `subtexel_bits` (as a profile's oracle samples), by name.
std::map<std::string, Image> run_stages(BloomParams p, const Image& scene, int subtexel_bits);

/// A w x h image with every pixel set to (v, v, v, 1).
Image constant_image(int w, int h, float v);

/// Max |a - b| over RGB, skipping pixels where either is non-finite.
double max_abs_diff(ConstImageView a, ConstImageView b);

/// True when both images have the same size and identical bits in every channel.
bool bit_identical(ConstImageView a, ConstImageView b);

/// bit_identical, except that any NaN equals any NaN. When two NaNs meet (an input NaN and an
/// Inf - Inf), IEEE 754 leaves open which one comes out, and on x86 the compiler may commute
/// an addition's operands, which decides it: sign and payload of NaN are not part of "same bits".
bool same_bits_nan_agnostic(ConstImageView a, ConstImageView b);
/// The same for one value.
bool same_bits_nan_agnostic(float a, float b);

/// Count of NaN values over all channels.
std::size_t count_nan(ConstImageView img);

/// The generic row kernels, then every wider instruction set this CPU has (AVX2, AVX-512F).
std::vector<BlurIsa> isas();

/// A fresh folder under the system temporary folder, removed with everything in it.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  /// Names of everything in the folder (not recursive), sorted.
  std::vector<std::string> listing() const;

 private:
  fs::path path_;
};

std::string read_bytes(const std::string& path);
void write_bytes(const std::string& path, const std::string& bytes);

struct CliResult {
  int code = -1;  ///< exit status; 128 + signal when the process was killed by one
  std::string out, err;
};

/// Runs `bloomref ARGS` (the build's executable) in `cwd` (the current folder when empty);
/// `env` (NAME=value ...) is put before the command. stdout and stderr go to files of a folder
/// of the call's own, so test cases run in parallel by ctest never read each other's.
CliResult run_cli(const std::string& args, const std::string& env = "", const fs::path& cwd = {});

/// Starts `bloomref ARGS` in `cwd` without waiting for it, with `env` (NAME=value) added to the
/// environment, stdout and stderr discarded; returns its process id.
int spawn_cli(const std::vector<std::string>& args, const fs::path& cwd,
              const std::vector<std::string>& env = {});
/// Waits for a process spawn_cli started; returns its exit status, 128 + signal when a signal
/// ended it.
int wait_cli(int pid);
/// Whether process `pid` has a file open in the folder `dir`, named or not (/proc/PID/fd: an
/// unnamed O_TMPFILE file shows as "DIR/#INODE (deleted)").
bool has_open_file_in(int pid, const fs::path& dir);

}  // namespace bloomref::test
