#pragma once
// Typed errors. Library code throws these and never prints; a stage's main() catches
// them, logs the message and exits with the code of the error kind.
#include <stdexcept>
#include <string>

namespace fourd {

// Exit codes shared by every executable.
enum ExitCode : int {
  kExitOk = 0,
  kExitFailure = 1,      // unexpected internal failure
  kExitUsage = 2,        // bad command line
  kExitConfig = 3,       // bad session.yaml or option value
  kExitInput = 4,        // bad input data (file, frame, camera)
  kExitIo = 5,           // cannot read/write a file
  kExitSolver = 6,       // a numeric method failed
};

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  virtual ExitCode exit_code() const { return kExitFailure; }
};

// Input data that does not make sense: names the file, take, camera and frame where it can.
class InputError : public Error {
 public:
  using Error::Error;
  ExitCode exit_code() const override { return kExitInput; }
};

// A command-line mistake: an unknown name, contradictory options, text that is not a frame
// range.
class UsageError : public Error {
 public:
  using Error::Error;
  ExitCode exit_code() const override { return kExitUsage; }
};

// An unknown key or an out-of-range value in a config file or on the command line.
class ConfigError : public Error {
 public:
  using Error::Error;
  ExitCode exit_code() const override { return kExitConfig; }
};

// A file that cannot be opened, read or written.
class IoError : public Error {
 public:
  using Error::Error;
  ExitCode exit_code() const override { return kExitIo; }
};

// A numeric method that did not converge or met a singular system.
class SolverError : public Error {
 public:
  using Error::Error;
  ExitCode exit_code() const override { return kExitSolver; }
};

}  // namespace fourd
