// A long per-tick series of joints held in half the memory (issue 12: a one-hour program has
// 3.6 M ticks, and the compensation holds several such series at once).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "gcpipe/block.hpp"

namespace gcpipe::simulate {

/// Joints per tick in about 20.6 bytes a tick instead of 40: a double base per block of kBlock
/// ticks (the block's first value, kept exactly) and a float offset from it per tick.
/// A float alone would not do: C is unwrapped up to +-36000 deg, where a float's step is 2-4 mdeg.
/// An offset within a block is what an axis covers in 64 ms, so its rounding (half a float step
/// of that distance) stays below 0.5 nm at 100 mm/s and 2e-6 deg at 720 deg/s (the circle test's
/// C at 4 pi): far below the 0.1 um the compensated program is written with.
/// A series made exact (kExact) holds doubles until compact() is called: the nominal run's raw
/// samples are planned on in full precision (the plan's decisions, and so the cycle time, must
/// not depend on storage), then kept compact for the learning and the figures.
/// Read by value: a compact series holds no Axes to refer to.
class JointSeries {
 public:
  static constexpr std::size_t kBlockBits = 6;
  static constexpr std::size_t kBlock = std::size_t{1} << kBlockBits;
  enum Storage { kCompact, kExact };

  explicit JointSeries(Storage storage = kCompact) : exact_(storage == kExact) {}

  std::size_t size() const { return exact_ ? full_.size() : offset_.size(); }
  bool empty() const { return size() == 0; }
  void reserve(std::size_t n) {
    if (exact_) return full_.reserve(n);
    offset_.reserve(n);
    base_.reserve((n + kBlock - 1) / kBlock);
  }
  void clear() {
    full_.clear();
    offset_.clear();
    base_.clear();
  }
  /// Empty, with room for n ticks: the memory kept if it holds them, else given back first (never
  /// two buffers at once).
  void clear_for(std::size_t n) {
    if ((exact_ ? full_.capacity() : offset_.capacity()) < n) release();
    clear();
    reserve(n);
  }
  /// Keeps the first n ticks (n <= size()): as if only they had been pushed.
  void truncate(std::size_t n) {
    if (exact_) return full_.resize(n);
    offset_.resize(n);
    base_.resize((n + kBlock - 1) / kBlock);
  }
  void shrink_to_fit() {
    full_.shrink_to_fit();
    offset_.shrink_to_fit();
    base_.shrink_to_fit();
  }
  /// Gives the memory back (clear() keeps it).
  void release() {
    std::vector<Axes>().swap(full_);
    std::vector<Offset>().swap(offset_);
    std::vector<Axes>().swap(base_);
  }
  /// From here on compact: the exact values are stored again as base and offsets, and freed.
  void compact() {
    if (!exact_) return;
    exact_ = false;
    reserve(full_.size());
    for (const Axes& x : full_) push_back(x);
    std::vector<Axes>().swap(full_);
  }

  void push_back(const Axes& x) {
    if (exact_) return full_.push_back(x);
    if ((offset_.size() & (kBlock - 1)) == 0) base_.push_back(x);
    const Axes& b = base_.back();
    Offset o;
    for (std::size_t i = 0; i < kNumAxes; ++i) o[i] = static_cast<float>(x[i] - b[i]);
    offset_.push_back(o);
  }

  /// Axis `axis` at tick n.
  double at(std::size_t n, std::size_t axis) const {
    if (exact_) return full_[n][axis];
    return base_[n >> kBlockBits][axis] + static_cast<double>(offset_[n][axis]);
  }
  Axes operator[](std::size_t n) const {
    if (exact_) return full_[n];
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
  bool exact_;
  std::vector<Axes> full_;      // the values, while exact
  std::vector<Axes> base_;      // compact: the value of tick k * kBlock
  std::vector<Offset> offset_;  // compact: per tick, from its block's base
};

}  // namespace gcpipe::simulate
