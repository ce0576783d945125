// The process-wide request to stop (SIGINT/SIGTERM). The CLI's signal handler sets it; every loop
// whose length an input decides (reading a line, expanding a cycle, running a loop, analysing
// engagement) polls it, so a run ends within a second of the signal wherever it is. It lives in
// common, below every stage, so that stages need not depend on the pipeline to obey it.
#pragma once

#include <stdexcept>

namespace gcpipe {

/// Records `sig` as the reason to stop; async-signal-safe. Returns the signal recorded before
/// (0 when this is the first request).
int request_stop(int sig) noexcept;
bool stop_requested() noexcept;
/// The signal that asked to stop, 0 when none.
int stop_signal() noexcept;

/// Thrown by a long loop that saw the request: the CLI catches it and exits 128 + signal, leaving
/// no output under its final name.
struct Stopped : std::runtime_error {
  Stopped();
};

/// Throws Stopped once a stop was requested.
inline void throw_if_stop_requested() {
  if (stop_requested()) throw Stopped();
}

}  // namespace gcpipe
