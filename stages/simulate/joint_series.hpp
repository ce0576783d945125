// A long per-tick series of joints held in half the memory (issue 12: a one-hour program has
// 3.6 M ticks, and the compensation holds several such series at once).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <vector>

#include <sys/mman.h>

#include "gcpipe/block.hpp"

namespace gcpipe::simulate {

/// Joints per tick in about 20.6 bytes a tick instead of 40: a double base per block of kBlock
/// ticks (the block's first value, kept exactly) and a float offset from it per tick.
/// A float alone would not do: C is unwrapped up to +-36000 deg, where a float's step is 2-4 mdeg.
/// An offset within a block is what an axis covers in 64 ms, so its rounding (half a float step
/// of that distance) stays below 0.5 nm at 100 mm/s and 2e-6 deg at 720 deg/s (the circle test's
/// C at 4 pi): far below the 0.1 um the compensated program is written with.
/// A series made exact (kExact) holds doubles until its ticks are compacted: the nominal run's raw
/// samples are planned on in full precision (the plan's decisions, and so the cycle time, must
/// not depend on storage), then kept compact for the learning and the figures. The planner
/// compacts the ticks behind the chunk it plans as it goes (compact_before), so the exact values
/// are held in pages of kPage ticks that go as they are compacted: no copy of the series is ever
/// made, and the exact and the compact series are never both held whole.
/// Read by value: a compact series holds no Axes to refer to.
class JointSeries {
 public:
  static constexpr std::size_t kBlockBits = 6;
  static constexpr std::size_t kBlock = std::size_t{1} << kBlockBits;
  static constexpr std::size_t kPageBits = 16;
  static constexpr std::size_t kPage = std::size_t{1} << kPageBits;  // 2.6 MB of exact values
  enum Storage { kCompact, kExact };

  explicit JointSeries(Storage storage = kCompact) : exact_(storage == kExact) {}

  std::size_t size() const { return exact_ ? size_ : offset_.size(); }
  bool empty() const { return size() == 0; }
  void reserve(std::size_t n) {
    if (exact_) return pages_.reserve((n + kPage - 1) / kPage);
    offset_.reserve(n);
    base_.reserve((n + kBlock - 1) / kBlock);
  }
  void clear() {
    pages_.clear();
    size_ = compacted_ = 0;
    offset_.clear();
    base_.clear();
  }
  /// Keeps the first n ticks (n <= size(); not below the compacted ticks of an exact series): as
  /// if only they had been pushed.
  void truncate(std::size_t n) {
    if (exact_) {
      size_ = n;
      pages_.resize((n + kPage - 1) / kPage);
      return;
    }
    offset_.resize(n);
    base_.resize((n + kBlock - 1) / kBlock);
  }
  void shrink_to_fit() {
    pages_.shrink_to_fit();
    offset_.shrink_to_fit();
    base_.shrink_to_fit();
  }
  /// Gives the memory back (clear() keeps it).
  void release() {
    std::vector<Page>().swap(pages_);
    size_ = compacted_ = 0;
    std::vector<Offset>().swap(offset_);
    std::vector<Axes>().swap(base_);
  }
  /// Ticks before `n` are read compact from here on, and the pages of exact values wholly before
  /// it are freed. The compact values are those of a compact series pushed the same ticks.
  void compact_before(std::size_t n) {
    if (!exact_) return;
    n = std::min(n, size_);
    if (offset_.capacity() < size_) {  // room for every tick at once: the compact series never grows by copying
      offset_.reserve(size_);
      base_.reserve((size_ + kBlock - 1) / kBlock);
    }
    for (; compacted_ < n; ++compacted_) push_compact(exact_at(compacted_));
    for (std::size_t p = 0; (p + 1) * kPage <= compacted_ && p < pages_.size(); ++p) pages_[p].reset();
  }
  /// From here on compact: every tick read at the compact series' precision; the exact values freed.
  void compact() {
    if (!exact_) return;
    compact_before(size_);
    std::vector<Page>().swap(pages_);
    size_ = compacted_ = 0;
    exact_ = false;
  }

  void push_back(const Axes& x) {
    if (!exact_) return push_compact(x);
    if ((size_ & (kPage - 1)) == 0) pages_.push_back(new_page());
    pages_.back()[size_ & (kPage - 1)] = x;
    ++size_;
  }

  /// Axis `axis` at tick n.
  double at(std::size_t n, std::size_t axis) const {
    if (exact_ && n >= compacted_) return exact_at(n)[axis];
    return base_[n >> kBlockBits][axis] + static_cast<double>(offset_[n][axis]);
  }
  Axes operator[](std::size_t n) const {
    if (exact_ && n >= compacted_) return exact_at(n);
    const Axes& b = base_[n >> kBlockBits];
    const Offset& o = offset_[n];
    Axes x;
    for (std::size_t i = 0; i < kNumAxes; ++i) x[i] = b[i] + static_cast<double>(o[i]);
    return x;
  }
  /// For loops over many ticks (the learning operator): whether the series is still exact, and
  /// its compact arrays, tick n's axis i at base_data()[(n >> kBlockBits) * kNumAxes + i] +
  /// offset_data()[n * kNumAxes + i].
  bool exact() const { return exact_; }
  const double* base_data() const { return base_.empty() ? nullptr : base_.front().data(); }
  const float* offset_data() const { return offset_.empty() ? nullptr : offset_.front().data(); }
  Axes front() const { return (*this)[0]; }
  Axes back() const { return (*this)[size() - 1]; }

 private:
  using Offset = std::array<float, kNumAxes>;
  // A page is mapped from the system and unmapped when freed: a page freed into malloc's heap
  // stays resident as a hole the growing compact series cannot use (measured: the one-hour
  // program peaked at 261 MB that way, against 228 MB with no compaction during the plan).
  struct Unmap {
    void operator()(Axes* p) const { ::munmap(p, kPage * sizeof(Axes)); }
  };
  using Page = std::unique_ptr<Axes[], Unmap>;
  static Page new_page() {
    void* p = ::mmap(nullptr, kPage * sizeof(Axes), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return Page(static_cast<Axes*>(p));
  }
  const Axes& exact_at(std::size_t n) const { return pages_[n >> kPageBits][n & (kPage - 1)]; }
  void push_compact(const Axes& x) {
    if ((offset_.size() & (kBlock - 1)) == 0) base_.push_back(x);
    const Axes& b = base_.back();
    Offset o;
    for (std::size_t i = 0; i < kNumAxes; ++i) o[i] = static_cast<float>(x[i] - b[i]);
    offset_.push_back(o);
  }
  bool exact_;
  std::vector<Page> pages_;     // exact: the values in pages of kPage ticks (freed once compacted)
  std::size_t size_ = 0;        // exact: ticks pushed
  std::size_t compacted_ = 0;   // exact: ticks before this are read from the compact arrays
  std::vector<Axes> base_;      // compact: the value of tick k * kBlock
  std::vector<Offset> offset_;  // compact: per tick, from its block's base
};

}  // namespace gcpipe::simulate
