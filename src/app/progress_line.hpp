// The one progress line of the command line: a line on standard error,
// rewritten in place ("\r" ... ), ended with a newline when it goes away.
// The caller decides whether it is shown (not quiet; a terminal, or asked
// for) and what it says.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace lgvi::app {

class ProgressLine {
 public:
  explicit ProgressLine(bool enabled) : enabled_(enabled), start_(clock::now()) {}
  ~ProgressLine() {
    if (shown_) std::fputs("\n", stderr);
  }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  bool enabled() const { return enabled_; }
  /// Seconds since the line was made.
  double elapsed() const { return std::chrono::duration<double>(clock::now() - start_).count(); }
  /// Replaces the line's text (padded, so that a shorter text covers a longer one).
  void show(const std::string& text) {
    if (!enabled_) return;
    std::fprintf(stderr, "\r%s   ", text.c_str());
    std::fflush(stderr);
    shown_ = true;
  }

 private:
  using clock = std::chrono::steady_clock;
  bool enabled_;
  clock::time_point start_;
  bool shown_ = false;
};

}  // namespace lgvi::app
