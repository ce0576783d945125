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

namespace gcpipe {
namespace {

std::size_t resident_mb() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  unsigned long size = 0, resident = 0;
  const int n = f ? std::fscanf(f, "%lu %lu", &size, &resident) : 0;
  if (f) std::fclose(f);
  return n == 2 ? resident * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE)) >> 20 : 0;
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

}  // namespace
}  // namespace gcpipe
