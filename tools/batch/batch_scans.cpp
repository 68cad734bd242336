// hgdeform batch: the scans of INPUT_DIR (top level or, with --recursive, the tree), each with
// its output path, its scenario (its own beside it, else the default) and its size.
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <exception>
#include <map>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "batch_internal.h"
#include "hgdeform/io/io.h"

namespace hgdcli {
namespace batch {

namespace {

bool isScanFile(const fs::path& p) {
  const std::string e = lowerExtension(p);
  // Not .txt: too common a name for notes and logs in a folder of scans.
  return e == ".ply" || e == ".pcd" || e == ".obj" || e == ".xyz" || e == ".off" || e == ".stl";
}

bool hidden(const fs::path& p) {
  const std::string name = p.filename().string();
  return !name.empty() && name[0] == '.';
}

/// Why `p`, a scan's own scenario, is there but cannot be read as a file ("" when it is a
/// regular file, links followed, or nothing is there).
std::string unreadableScenario(const fs::path& p) {
  std::error_code e1, e2;
  const fs::file_status own = fs::symlink_status(p, e1);
  if (own.type() == fs::file_type::not_found) return {};  // (e1 says so too)
  if (e1) return e1.message();                            // e.g. a folder on the way that cannot be searched
  const fs::file_status target = fs::status(p, e2);       // links followed
  if (fs::is_symlink(own)) {
    std::error_code e3;
    const fs::path to = fs::read_symlink(p, e3);
    if (e2 && e2.value() == ELOOP) return "a loop of symbolic links (" + e2.message() + ")";
    if (e2 || !fs::exists(target))
      return "a dangling symbolic link (" + to.string() + ": " +
             (e2 ? e2.message() : std::string("No such file or directory")) + ")";
  } else if (e2) {
    return e2.message();
  }
  if (fs::is_regular_file(target)) return {};
  const std::string via = fs::is_symlink(own) ? " (through a symbolic link)" : "";
  if (fs::is_directory(target)) return "a directory" + via + ", not a file";
  const std::string what = fs::is_fifo(target)                                          ? "a FIFO"
                           : fs::is_socket(target)                                      ? "a socket"
                           : fs::is_block_file(target) || fs::is_character_file(target) ? "a device"
                                                                                        : "a special file";
  return what + via + ", not a regular file";
}

}  // namespace

void RunInputs::add(const fs::path& input) {
  struct stat st {};
  if (::stat(input.c_str(), &st) == 0)
    by_id_.emplace(
        std::make_pair(static_cast<std::uint64_t>(st.st_dev), static_cast<std::uint64_t>(st.st_ino)),
        input.string());
}

void RunInputs::refuse(const std::string& output) const {
  struct stat st {};
  if (::stat(output.c_str(), &st) != 0) return;  // no file there: none of the inputs
  const auto it = by_id_.find({static_cast<std::uint64_t>(st.st_dev), static_cast<std::uint64_t>(st.st_ino)});
  if (it != by_id_.end()) hgd::refuseInputs(output, {it->second});
}

fs::path normalisedAbsolute(const fs::path& p) {
  fs::path n = fs::weakly_canonical(fs::absolute(p)).lexically_normal();
  if (!n.has_filename() && n.has_parent_path() && n != n.root_path()) n = n.parent_path();
  return n;
}

std::string lowerExtension(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& ch : e) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}

std::vector<Scan> listScans(const Config& c, std::vector<batch::SkippedEntry>& skipped, RunInputs& inputs) {
  std::vector<fs::path> files;
  std::error_code ec;
  auto consider = [&](const fs::directory_entry& e) {
    if (hidden(e.path())) return;
    std::error_code e1, e2;
    const fs::file_status own = e.symlink_status(e1);
    const fs::file_status target = e.status(e2);  // links followed
    const bool link = !e1 && fs::is_symlink(own);
    const std::string rel = e.path().lexically_relative(c.input_dir).generic_string();
    if (e1 || (e2 && !link)) {  // not even its kind can be known: say why (e.g. too long a path)
      const std::error_code& why = e1 ? e1 : e2;
      if (isScanFile(e.path()))
        skipped.push_back({rel, why.value() == ENAMETOOLONG ? "its path is longer than the system allows (" +
                                                                  std::to_string(e.path().native().size()) +
                                                                  " bytes; " + why.message() + ")"
                                                            : "cannot be examined: " + why.message()});
      return;
    }
    if (link && !fs::exists(target)) {  // dangling, or a loop of links
      std::error_code e3;
      const fs::path to = fs::read_symlink(e.path(), e3);
      if (isScanFile(e.path()) || isScanFile(to))
        skipped.push_back({rel, "a dangling symbolic link (" + to.string() + ": " +
                                    (e2 ? e2.message() : std::string("No such file or directory")) + ")"});
      return;
    }
    if (link && fs::is_directory(target)) {
      if (c.recursive)
        skipped.push_back({rel,
                           "a symbolic link to a folder: not followed, to avoid cycles (give the folder "
                           "it names as INPUT_DIR to process it)"});
      return;
    }
    if (!isScanFile(e.path()) || fs::is_directory(target)) return;
    if (fs::is_regular_file(target)) {
      files.push_back(e.path());
      return;
    }
    const std::string what = fs::is_fifo(target)                                          ? "a FIFO"
                             : fs::is_socket(target)                                      ? "a socket"
                             : fs::is_block_file(target) || fs::is_character_file(target) ? "a device"
                                                                                          : "a special file";
    skipped.push_back({rel, what + (link ? " (through a symbolic link)" : "") + ", not a regular file"});
  };
  if (c.recursive) {
    fs::recursive_directory_iterator it(c.input_dir, fs::directory_options::skip_permission_denied, ec), end;
    if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
    for (; it != end; it.increment(ec)) {
      if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
      if (hidden(it->path())) {
        std::error_code e2;
        if (it->is_directory(e2)) it.disable_recursion_pending();  // .git, .cache, ...
        continue;
      }
      consider(*it);
    }
  } else {
    fs::directory_iterator it(c.input_dir, ec), end;
    if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
    for (; it != end; it.increment(ec)) {
      if (ec) throw std::runtime_error(c.input_dir.string() + ": cannot list: " + ec.message());
      consider(*it);
    }
  }

  std::vector<Scan> scans;
  inputs.add(c.scenario_path);
  for (const auto& f : files) {
    Scan s;
    s.input = f;
    s.rel = f.lexically_relative(c.input_dir).generic_string();
    fs::path out_rel(s.rel);
    if (c.format != "same") out_rel.replace_extension("." + c.format);
    s.out_rel = out_rel.generic_string();
    s.output = c.output_dir / out_rel;
    const fs::path own = f.parent_path() / (f.stem().string() + ".json");
    std::error_code e1, e2;
    if (fs::is_regular_file(own, e1) && !fs::equivalent(own, c.scenario_path, e2)) {
      s.scenario = own;
      s.own_scenario = true;
      inputs.add(own);
    } else if (const std::string why = unreadableScenario(own); !why.empty()) {
      // There but not a file to read: the scan fails rather than take the default in silence.
      s.scenario = own;
      s.own_scenario = true;
      s.error = own.string() + ": cannot read the scan's own scenario: " + why;
    } else {
      s.scenario = c.scenario_path;
    }
    s.size = fs::file_size(f, e1);
    if (e1) s.size = 0;
    inputs.add(f);
    scans.push_back(std::move(s));
  }
  std::sort(scans.begin(), scans.end(), [](const Scan& a, const Scan& b) { return a.rel < b.rel; });
  std::sort(skipped.begin(), skipped.end(),
            [](const batch::SkippedEntry& a, const batch::SkippedEntry& b) { return a.path < b.path; });
  std::map<std::string, std::string> writer;  // output -> the scan writing it
  for (auto& s : scans) {
    auto [it, fresh] = writer.emplace(s.out_rel, s.rel);
    if (!fresh) {
      s.error = "output " + s.out_rel + " would also be written by " + it->second + " (use --format same)";
      continue;
    }
    try {
      inputs.refuse(s.output.string());
    } catch (const std::exception& e) {
      s.error = e.what();
    }
  }
  return scans;
}

}  // namespace batch
}  // namespace hgdcli
