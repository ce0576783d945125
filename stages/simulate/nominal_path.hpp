// Internal to stages/simulate: the nominal tool-tip polyline of a recorded run, made as a run
// reaches it (evaluate(), the planner's check of its reference).
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <stdexcept>
#include <span>
#include <vector>

#include "simulate.hpp"

namespace gcpipe::simulate {

/// The nominal tool-tip polyline of a recorded run (the raw samples' tips, repeated points
/// dropped), made as an evaluated run reaches it and pushed into a
/// streaming ContourSearch, which keeps only its window: the whole polyline, 28 bytes a tick, is
/// never held. The search gets the same points at the same calls as over a whole polyline.
class NominalPolyline {
 public:
  /// From raw tick `first_tick` on (a window of a run that began earlier). `keep_all`: every
  /// tick's index is kept, so that rewind() can start a new run over the same points.
  NominalPolyline(const Model& model, const Nominal& nom, ContourSearch& search, std::size_t first_tick = 0,
                  bool keep_all = false)
      : model_(model), nom_(nom), search_(search), walked_(first_tick), first_tick_(first_tick),
        origin_(first_tick), asked_(first_tick), keep_all_(keep_all) {}

  /// The polyline index of raw tick k (clamped to the last); k never decreases between calls
  /// (between rewinds).
  std::size_t index_of_tick(std::size_t k) {
    if (nom_.raw.empty()) return 0;
    k = std::min(k, nom_.raw.size() - 1);
    if (k < asked_) throw std::logic_error("NominalPolyline: raw ticks asked for out of order");
    asked_ = k;
    while (walked_ <= k) walk();
    if (!keep_all_)
      while (first_tick_ < k) index_.pop_front(), ++first_tick_;
    return index_[k - first_tick_];
  }

  /// A new run over the points made so far (keep_all only): raw ticks are asked for from the
  /// first again.
  void rewind() {
    if (!keep_all_) throw std::logic_error("NominalPolyline: rewind() needs keep_all");
    asked_ = origin_;
  }

  /// Makes points until the search holds `count` of them or the polyline ends.
  void fill(std::size_t count) {
    while (search_.size() < count && walked_ < nom_.raw.size()) walk();
  }

 private:
  void walk() {
    const std::size_t k = walked_++;
    const Vec3 tip = forward_kinematics(model_.kin, nom_.raw[k], tool_length_of(model_, nom_.brief[nom_.block[k]])).tip;
    if (search_.size() == 0 || dist3(last_, tip) > 1e-9) search_.push(tip), last_ = tip;
    index_.push_back(static_cast<std::uint32_t>(search_.size() - 1));
  }

  const Model& model_;
  const Nominal& nom_;
  ContourSearch& search_;
  std::size_t walked_ = 0;               // raw ticks turned into points so far (from first_tick_)
  Vec3 last_{};                          // the newest point
  std::deque<std::uint32_t> index_;      // polyline index of raw ticks first_tick_ .. walked_ - 1
  std::size_t first_tick_ = 0;           // raw tick of index_.front()
  std::size_t origin_ = 0;               // the first raw tick of the polyline
  std::size_t asked_ = 0;                // the raw tick asked for last (since the last rewind)
  bool keep_all_ = false;
};

}  // namespace gcpipe::simulate
