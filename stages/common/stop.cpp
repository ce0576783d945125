#include "gcpipe/stop.hpp"

#include <atomic>
#include <string>

namespace gcpipe {

namespace {
std::atomic<int> g_stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "set from a signal handler");
}  // namespace

int request_stop(int sig) noexcept { return g_stop_signal.exchange(sig); }
bool stop_requested() noexcept { return g_stop_signal.load(std::memory_order_relaxed) != 0; }
int stop_signal() noexcept { return g_stop_signal.load(); }

Stopped::Stopped() : std::runtime_error("interrupted by signal " + std::to_string(stop_signal())) {}

}  // namespace gcpipe
