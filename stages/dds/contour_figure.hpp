// The live contour-error figure of `gcpipe monitor --plot FILE.png`: the simulated machine's
// contour error over machine time, redrawn while a program streams through. No DDS in here: the
// monitor hands it the ticks of the simulate stage's telemetry.
//
// Memory is bounded whatever the program's length: ticks are kept as the largest error per
// bucket of `stride` ticks; when `capacity` buckets are full, neighbours merge (largest of the
// two) and the stride doubles. A peak is never lost, only its neighbours' detail.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace gcpipe::dds {

class ContourFigure {
 public:
  /// One drawn point: the largest error of its stretch of ticks, at that tick's time.
  struct Point {
    double time = 0;     //!< [s]
    double contour = 0;  //!< [mm]
  };

  /// `png`: written as png.part and renamed, so a viewer never reads half a file.
  explicit ContourFigure(std::filesystem::path png, std::size_t capacity = 2048);

  /// One simulated tick: machine time [s], contour error [mm] (0 on rapids, which carry none).
  void add(double time, double contour);
  /// Redraws the file if ticks arrived since the last draw; `title` names the program.
  void draw(const std::string& title);

  std::uint64_t ticks() const { return ticks_; }
  double max_mm() const { return max_; }
  /// What draw() plots: at most `capacity` points.
  const std::vector<Point>& points() const { return buckets_; }

 private:
  void merge_pairs();

  std::filesystem::path png_;
  std::size_t capacity_;
  std::uint64_t stride_ = 1, in_bucket_ = 0, ticks_ = 0, cutting_ = 0, drawn_ticks_ = 0;
  double max_ = 0, sum_sq_ = 0, now_ = 0;
  std::vector<Point> buckets_;
};

}  // namespace gcpipe::dds
