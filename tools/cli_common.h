// Command-line parsing shared by every tool: CLI11 (Debian's libcli11-dev, header-only) with one
// convention for all of them:
//   --help     the options with their defaults and descriptions, on stdout, exit 0
//   --version  "<tool> <version>" on stdout, exit 0
//   usage errors (unknown option, missing required option or argument, bad value) go to stderr as
//   "<tool>: <what>\n(see '<tool> --help')", exit 2; failures of the work itself exit 1.
#pragma once

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>

#include "hgdeform/app/memory.h"
#include "hgdeform/version.h"

namespace hgdcli {

/// A usage error found after parsing (options that contradict each other, a path that cannot be
/// one): exit 2 like CLI11's own.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// `--memory BYTES` as the user wrote it ("1.5G", "800M", hgd::parseByteCount); "" for none (0).
inline std::uint64_t memoryOption(const std::string& text) {
  std::uint64_t bytes = 0;
  if (!text.empty() && !hgd::parseByteCount(text, &bytes))
    throw UsageError("--memory takes a byte count such as 1500000000, 1.5G or 800M (got '" + text + "')");
  return bytes;
}

/// This process's peak resident memory in MB (VmHWM in /proc/self/status), 0 where it cannot be
/// read. Not getrusage's ru_maxrss: that also counts the image this process was forked from
/// before its exec (a benchmark or a script holding gigabytes would show as ours).
inline double peakResidentMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::strtod(line.c_str() + 6, nullptr) / 1024.0;  // kB
  return 0;
}

/// `tool version`, e.g. "hgdeform deform 0.2.0".
inline std::string versionLine(const std::string& tool) {
  return tool + " " + hgd::version();
}

/// An app with the conventions above: `tool` is the name shown in usage lines and messages.
inline void configureApp(CLI::App& app, const std::string& tool) {
  app.name(tool);
  app.set_help_flag("-h,--help", "this help");
  app.set_version_flag("--version", versionLine(tool), "print \"" + tool + " VERSION\" and exit");
  // A repeated option: the last one counts (as the hand-written parsers did).
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app.get_formatter()->column_width(32);
  app.footer("Exit status: 0 on success, 1 when the work failed, 2 on usage errors.");
}

/// Writes a usage error the way every tool does; returns 2.
inline int usageError(const std::string& tool, const std::string& what) {
  std::fprintf(stderr, "%s: %s\n(see '%s --help')\n", tool.c_str(), what.c_str(), tool.c_str());
  return 2;
}

/// Parses; returns -1 when the program should go on, else the exit status (0 after --help or
/// --version, 2 after a usage error). With `print` false nothing is printed (MPI ranks other
/// than 0).
inline int parse(CLI::App& app, int argc, const char* const* argv, bool print = true) {
  try {
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::CallForHelp&) {
    if (print) std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const CLI::CallForAllHelp&) {
    if (print) std::fputs(app.help("", CLI::AppFormatMode::All).c_str(), stdout);
    return 0;
  } catch (const CLI::CallForVersion& e) {
    if (print) std::printf("%s\n", e.what());
    return 0;
  } catch (const CLI::Success&) {  // a flag that printed what it was asked for (--keys-markdown)
    return 0;
  } catch (const CLI::ParseError& e) {
    return print ? usageError(app.get_name(), e.what()) : 2;
  }
}

/// A validator for integer options: the value must be an integer from lo to hi.
inline CLI::Validator integerFrom(long lo, long hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long v = std::strtol(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0' || errno != 0 || v < lo || v > hi)
          return "must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + " (got '" +
                 text + "')";
        return {};
      },
      "", "integer");
}

/// A picture or window size option, --size WxH with each side from `min_side` to `max_side`
/// (hgd::kMaxPictureSide for pictures): the sides go to `width` and `height` once valid.
inline CLI::Option* addSizeOption(CLI::App& app, const std::string& help, int min_side, int max_side,
                                  int& width, int& height) {
  return app.add_option("--size", help)
      ->check(CLI::Validator(
          [min_side, max_side, &width, &height](std::string& s) -> std::string {
            int w = 0, h = 0;
            char rest = 0;
            if (std::sscanf(s.c_str(), "%6dx%6d%c", &w, &h, &rest) != 2 || w < min_side || h < min_side ||
                w > max_side || h > max_side)
              return "must be WIDTHxHEIGHT, each from " + std::to_string(min_side) + " to " +
                     std::to_string(max_side) + " (got '" + s + "')";
            width = w;
            height = h;
            return {};
          },
          "", "size"))
      ->type_name("WxH");
}

/// An integer option from `lo` to `hi`, shown as "N" in the help.
template <class Int>
CLI::Option* addCount(CLI::App& app, const std::string& name, Int& value, const std::string& help, long lo,
                      long hi) {
  return app.add_option(name, value, help)->check(integerFrom(lo, hi))->type_name("N");
}

/// A validator for words from a fixed list.
inline CLI::Validator oneOf(const std::vector<std::string>& words) {
  std::string list;
  for (std::size_t i = 0; i < words.size(); ++i)
    list += (i == 0 ? "" : i + 1 == words.size() ? " or " : ", ") + words[i];
  return CLI::Validator(
      [words, list](std::string& text) -> std::string {
        for (const auto& w : words)
          if (text == w) return {};
        return "must be " + list + " (got '" + text + "')";
      },
      "", "word");
}

}  // namespace hgdcli
