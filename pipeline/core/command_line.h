#pragma once
// Command-line parsing with the exit codes every fourd executable uses (header only: the
// executables link CLI11, the core library does not).
#include <CLI/CLI.hpp>
#include <optional>

#include "pipeline/core/error.h"

namespace fourd {

// Parses argv into `app`. Returns the code to exit with when the program stops here (--help:
// printed, kExitOk; a bad command line: the message, kExitUsage); nothing when it goes on.
inline std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  return std::nullopt;
}

}  // namespace fourd
