// The scratch store of the long series (issue 12: memory that does not grow with the program):
// values survive spilling to the scratch file, growth, the resident-set trimmer and copies; the
// pages really leave the process; a full disk is an error that says what to do, not a SIGBUS.
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include <sys/resource.h>
#include <unistd.h>

#include "gcpipe/block_store.hpp"
#include "gcpipe/scratch.hpp"
#include "joint_series.hpp"

namespace gcpipe {
namespace {

std::size_t resident_mb() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  unsigned long size = 0, resident = 0;
  const int n = f ? std::fscanf(f, "%lu %lu", &size, &resident) : 0;
  if (f) std::fclose(f);
  return n == 2 ? resident * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE)) >> 20 : 0;
}

/// The peak resident set since the last reset_peak_resident() [MB], 0 if the kernel does not say.
std::size_t peak_resident_mb() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  char line[256];
  unsigned long kb = 0;
  while (f && std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmHWM: %lu kB", &kb) == 1) break;
  if (f) std::fclose(f);
  return kb >> 10;
}

/// Sets the peak resident set to the resident set now (Linux >= 4.0); false where not allowed.
bool reset_peak_resident() {
  std::FILE* f = std::fopen("/proc/self/clear_refs", "w");
  if (!f) return false;
  const bool ok = std::fputs("5", f) >= 0;
  return std::fclose(f) == 0 && ok;
}

/// Waits (up to 10 s) until the trimmer has dropped the spilled pages: the resident set is within
/// `slack` MB of `base`.
void settle_resident(std::size_t base, std::size_t slack) {
  for (int i = 0; i < 100 && resident_mb() > base + slack; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
}

double value_at(std::size_t i) { return 0.5 * static_cast<double>(i) + 1e-3 * static_cast<double>(i % 7); }

TEST(Scratch, ASmallArrayStaysInMemoryAndALongOneSpillsWithEveryValue) {
  ScratchArray<double> small;
  for (std::size_t i = 0; i < 1000; ++i) small.push_back(value_at(i));
  ScratchArray<double> big;
  const std::size_t n = 3 * ScratchBytes::kSpillBytes / sizeof(double);
  for (std::size_t i = 0; i < n; ++i) big.push_back(value_at(i));
  ASSERT_EQ(big.size(), n);
  for (std::size_t i = 0; i < 1000; ++i) ASSERT_EQ(small[i], value_at(i));
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(big[i], value_at(i)) << i;
  // A copy is a copy: changing it leaves the original.
  ScratchArray<double> copy = big;
  copy[5] = -1;
  EXPECT_EQ(big[5], value_at(5));
  big.resize(10);
  big.shrink_to_fit();
  EXPECT_EQ(big.size(), 10u);
  EXPECT_EQ(big[9], value_at(9));
  EXPECT_EQ(copy[n - 1], value_at(n - 1));
}

// The point of it all: 96 MB written into a scratch array leave the process's resident set
// within the trimmer's period, and read back whole afterwards. Waits up to 10 s for the trimmer
// (its period is 0.2 s) so that a loaded machine does not fail it; a store kept in memory would
// never get there.
TEST(Scratch, PagesWrittenLeaveTheResidentSetAndReadBackUnchanged) {
  const std::size_t before = resident_mb();
  ScratchArray<double> series;
  const std::size_t n = (std::size_t{96} << 20) / sizeof(double);
  for (std::size_t i = 0; i < n; ++i) series.push_back(value_at(i));
  std::size_t now = resident_mb();
  for (int i = 0; i < 100 && now > before + 24; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    now = resident_mb();
  }
  EXPECT_LE(now, before + 24) << "resident " << before << " MB before, " << now << " MB after writing 96 MB";
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(series[i], value_at(i)) << i;
}

TEST(Scratch, DiscardedFrontFreesItsPagesAndKeepsTheRest) {
  ScratchArray<double> series;
  const std::size_t n = 2 * ScratchBytes::kSpillBytes / sizeof(double);
  for (std::size_t i = 0; i < n; ++i) series.push_back(value_at(i));
  series.discard_before(n / 2);
  EXPECT_EQ(series[0], 0.0);  // a freed page reads as zeros
  for (std::size_t i = n / 2; i < n; ++i) ASSERT_EQ(series[i], value_at(i)) << i;
}

// A scratch directory that cannot be used: the values are kept in memory (with one warning).
TEST(Scratch, AnUnusableScratchDirectoryKeepsTheValuesInMemory) {
  ::setenv("GCPIPE_SCRATCH_DIR", "/nonexistent/gcpipe-scratch", 1);
  ScratchArray<double> series;
  const std::size_t n = 2 * ScratchBytes::kSpillBytes / sizeof(double);
  for (std::size_t i = 0; i < n; ++i) series.push_back(value_at(i));
  ::unsetenv("GCPIPE_SCRATCH_DIR");
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(series[i], value_at(i)) << i;
}

// No room on disk (here: a file size limit, which fallocate honours as it does a full disk): an
// exception that names the directory and what to do, where a page written through the mapping
// into a file without disk under it would have killed the process with SIGBUS.
TEST(Scratch, NoRoomForTheScratchFileIsAnErrorThatSaysWhatToDo) {
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit old{};
  ::getrlimit(RLIMIT_FSIZE, &old);
  rlimit small = old;
  small.rlim_cur = 4 << 20;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string what;
  try {
    ScratchArray<double> series;
    for (std::size_t i = 0; i < (std::size_t{64} << 20) / sizeof(double); ++i) series.push_back(value_at(i));
  } catch (const std::runtime_error& e) {
    what = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &old);
  EXPECT_NE(what.find("no room for"), std::string::npos) << what;
  EXPECT_NE(what.find("GCPIPE_SCRATCH_DIR"), std::string::npos) << what;
}

ResolvedBlock block_numbered(std::size_t i) {
  ResolvedBlock b;
  b.line = i + 1;
  b.text = "G1 X" + std::to_string(i) + ".125 Y-" + std::to_string(2 * i) + ".5 F1200 (a line longer than SSO)";
  b.comment = i % 3 == 0 ? "" : "note " + std::to_string(i);
  b.target[0] = static_cast<double>(i);
  return b;
}

TEST(BlockStore, HoldsBlocksWithTheirTextsInOrderAndSaysWhenFull) {
  const std::size_t n = 20000;  // 9 MB of blocks: well past the spill size
  BlockStore store(n);
  for (std::size_t i = 0; i < n; ++i) store.push_back(block_numbered(i));
  ASSERT_EQ(store.size(), n);
  const BlockStore copy = store;
  for (std::size_t i = 0; i < n; ++i) {
    const ResolvedBlock want = block_numbered(i);
    ASSERT_EQ(store[i].line, want.line);
    ASSERT_EQ(store[i].text, want.text);
    ASSERT_EQ(copy[i].comment, want.comment);
    ASSERT_EQ(store.span()[i].target[0], want.target[0]);
  }
  EXPECT_THROW(store.push_back(block_numbered(n)), std::length_error);
  BlockStore moved = std::move(store);
  EXPECT_EQ(moved.size(), n);
  EXPECT_EQ(moved.back().text, block_numbered(n - 1).text);
}

TEST(BlockStore, KeepsEachBlocksBriefBesideIt) {
  const std::size_t n = 5000;
  BlockStore store(n);
  for (std::size_t i = 0; i < n; ++i) {
    ResolvedBlock b = block_numbered(i);
    b.motion = i % 4 == 0 ? Motion::kRapid : Motion::kLinear;
    b.tool_length_active = i % 5 == 0;
    b.tool_length = 0.25 * static_cast<double>(i);
    b.stop = i + 1 == n ? ProgramStop::kEndRewind : ProgramStop::kNone;
    store.push_back(std::move(b));
  }
  const BlockStore copy = store;
  const BlockStore moved = std::move(store);
  for (const BlockStore* s : {&copy, &moved}) {
    ASSERT_EQ(s->briefs().size(), n);
    for (std::size_t i = 0; i < n; ++i) {
      const BlockBrief& b = s->briefs()[i];
      const ResolvedBlock& full = (*s)[i];
      ASSERT_EQ(b.line, full.line);
      ASSERT_EQ(b.motion, full.motion);
      ASSERT_EQ(b.tool_length_active, full.tool_length_active);
      ASSERT_EQ(b.tool_length, full.tool_length);
      ASSERT_EQ(b.stop, full.stop);
    }
  }
}

// Destroying a block reads its strings, so destroying a long program at once mapped every page of
// it in milliseconds, faster than the trimmer's poll: that was the peak of a one-hour program's
// run (22 MB at its end). 120,000 blocks are 56 MB: destroyed at once they raised the peak by
// 29-37 MB (three runs); dropped behind every MB, by 1-4 MB. The bound is the trimmer's 8 MB step
// twice.
TEST(BlockStore, DestroyingALongStoreDoesNotMapItWhole) {
  const std::size_t base = resident_mb();
  const std::size_t n = 120000;
  BlockStore store(n);
  for (std::size_t i = 0; i < n; ++i) store.push_back(block_numbered(i));
  settle_resident(base, 16);
  if (!reset_peak_resident()) GTEST_SKIP() << "/proc/self/clear_refs cannot be written here: the peak cannot be reset";
  const std::size_t before = resident_mb();
  store.clear();
  const std::size_t peak = peak_resident_mb();
  EXPECT_LE(peak, before + 16) << "resident " << before << " MB before destroying " << n << " blocks (" << n * sizeof(ResolvedBlock) / 1000000
                               << " MB), peak " << peak << " MB while destroying them";
}

// A plan that stops early (a program longer than max_machine_time) compacts the rest of the raw
// samples at once: 3 M ticks, 114 MB exact read and 59 MB compact written at gigabytes a second.
// In one go the peak rose by 26-30 MB (five runs); in steps of 2.5 MB with a trim after each, by
// 2-10 MB. The bound is the trimmer's 8 MB step twice.
TEST(JointSeries, CompactingALongSeriesAtOnceDoesNotMapItWhole) {
  const std::size_t base = resident_mb();
  const std::size_t n = 3000000;
  simulate::JointSeries series(simulate::JointSeries::kExact);
  for (std::size_t i = 0; i < n; ++i) {
    const double v = value_at(i);
    series.push_back({v, -v, 0.5 * v, 1e-3 * v, 2e-3 * v});
  }
  settle_resident(base, 16);
  if (!reset_peak_resident()) GTEST_SKIP() << "/proc/self/clear_refs cannot be written here: the peak cannot be reset";
  const std::size_t before = resident_mb();
  series.compact();
  const std::size_t peak = peak_resident_mb();
  EXPECT_LE(peak, before + 16) << "resident " << before << " MB before compacting " << n << " ticks, peak " << peak << " MB";
  for (std::size_t i = 0; i < n; i += 9973) ASSERT_NEAR(series[i][0], value_at(i), 1e-6) << i;
}

}  // namespace
}  // namespace gcpipe
