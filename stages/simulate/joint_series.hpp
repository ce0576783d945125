// A long per-tick series of joints held in half the memory (issue 12: a one-hour program has
// 3.6 M ticks, and the compensation holds several such series at once).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include "gcpipe/block.hpp"
#include "gcpipe/scratch.hpp"

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
/// compacts the ticks behind the chunk it plans as it goes (compact_before), and their exact
/// values' pages are freed as it does: the exact and the compact series are never both held whole.
/// Read by value: a compact series holds no Axes to refer to.
class JointSeries {
 public:
  static constexpr std::size_t kBlockBits = 6;
  static constexpr std::size_t kBlock = std::size_t{1} << kBlockBits;
  enum Storage { kCompact, kExact };

  explicit JointSeries(Storage storage = kCompact) : exact_(storage == kExact) {}

  std::size_t size() const { return exact_ ? values_.size() : offset_.size(); }
  bool empty() const { return size() == 0; }
  void reserve(std::size_t n) {
    if (exact_) return values_.reserve(n);
    offset_.reserve(n);
    base_.reserve((n + kBlock - 1) / kBlock);
  }
  void clear() {
    values_.clear();
    compacted_ = 0;
    offset_.clear();
    base_.clear();
  }
  /// Keeps the first n ticks (n <= size(); not below the compacted ticks of an exact series): as
  /// if only they had been pushed.
  void truncate(std::size_t n) {
    if (exact_) return values_.resize(n);
    offset_.resize(n);
    base_.resize((n + kBlock - 1) / kBlock);
  }
  void shrink_to_fit() {
    values_.shrink_to_fit();
    offset_.shrink_to_fit();
    base_.shrink_to_fit();
  }
  /// Gives the memory back (clear() keeps it).
  void release() {
    values_.release();
    compacted_ = 0;
    offset_.release();
    base_.release();
  }
  /// Ticks before `n` are read compact from here on, and the exact values wholly before it are
  /// freed. The compact values are those of a compact series pushed the same ticks.
  void compact_before(std::size_t n) {
    if (!exact_) return;
    n = std::min(n, values_.size());
    // In steps of 65,536 ticks (2.5 MB exact), the exact values freed behind each: a program
    // whose plan stopped early (longer than max_machine_time) is compacted whole here, at
    // gigabytes a second.
    constexpr std::size_t kStep = std::size_t{1} << 16;
    while (compacted_ < n) {
      const std::size_t step_end = std::min(n, compacted_ + kStep);
      for (; compacted_ < step_end; ++compacted_) push_compact(values_[compacted_]);
      values_.discard_before(compacted_);
      trim_scratch_if_grown();
    }
  }
  /// From here on compact: every tick read at the compact series' precision; the exact values freed.
  void compact() {
    if (!exact_) return;
    compact_before(values_.size());
    values_.release();
    compacted_ = 0;
    exact_ = false;
  }

  void push_back(const Axes& x) {
    if (!exact_) return push_compact(x);
    values_.push_back(x);
  }

  /// Axis `axis` at tick n.
  double at(std::size_t n, std::size_t axis) const {
    if (exact_ && n >= compacted_) return values_[n][axis];
    return base_[n >> kBlockBits][axis] + static_cast<double>(offset_[n][axis]);
  }
  Axes operator[](std::size_t n) const {
    if (exact_ && n >= compacted_) return values_[n];
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
  void push_compact(const Axes& x) {
    if ((offset_.size() & (kBlock - 1)) == 0) base_.push_back(x);
    const Axes& b = base_.back();
    Offset o;
    for (std::size_t i = 0; i < kNumAxes; ++i) o[i] = static_cast<float>(x[i] - b[i]);
    offset_.push_back(o);
  }
  // Scratch arrays (gcpipe/scratch.hpp): a long series lives in a scratch file's pages, not in
  // the process's memory, and growing one never copies it.
  bool exact_;
  ScratchArray<Axes> values_;     // exact: every tick (freed page by page as it is compacted)
  std::size_t compacted_ = 0;     // exact: ticks before this are read from the compact arrays
  ScratchArray<Axes> base_;       // compact: the value of tick k * kBlock
  ScratchArray<Offset> offset_;   // compact: per tick, from its block's base
};

}  // namespace gcpipe::simulate
