// SIGINT and SIGTERM as a request to stop: `lgvi run` stops at the next step
// boundary, `lgvi ensemble` at the next member (and its members' runs at the
// next step), with valid files. One handler and one flag for every command.
#pragma once

#include <csignal>

namespace lgvi::app {

/// Installs the SIGINT/SIGTERM handlers for its lifetime (restoring the
/// previous ones after) and clears the request on installation. For the
/// outermost scope of a command only: not nested (an inner one would clear a
/// request made before it) and not per thread (installing is not thread-safe).
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

/// The flag the handler sets to the signal's number: what the run loop polls
/// (SimulationOptions::stop_flag).
const volatile std::sig_atomic_t* stop_flag();

/// The signal that asked to stop (SIGINT or SIGTERM), 0 if none.
int stop_signal();

/// "SIGTERM" or "SIGINT", for messages.
const char* stop_signal_name();

/// The exit status of a command stopped by the signal: 143 for SIGTERM, 130
/// for SIGINT (128 + the signal's number, as a shell reports it).
int stop_exit_status();

}  // namespace lgvi::app
