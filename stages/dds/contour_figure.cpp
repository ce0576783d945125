#include "contour_figure.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <system_error>

#include "plot.hpp"

namespace gcpipe::dds {

ContourFigure::ContourFigure(std::filesystem::path png, std::size_t capacity)
    : png_(std::move(png)), capacity_(capacity < 2 ? 2 : capacity) {
  buckets_.reserve(capacity_);
}

void ContourFigure::add(double time, double contour) {
  ++ticks_;
  now_ = time;
  if (contour > 0) {
    ++cutting_;
    max_ = std::max(max_, contour);
    sum_sq_ += contour * contour;
  }
  if (in_bucket_ == 0) {
    if (buckets_.size() == capacity_) merge_pairs();
    buckets_.push_back({time, contour});
  } else if (contour > buckets_.back().contour) {
    buckets_.back() = {time, contour};
  }
  if (++in_bucket_ == stride_) in_bucket_ = 0;
}

void ContourFigure::merge_pairs() {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < buckets_.size(); i += 2) {
    Point b = buckets_[i];
    if (i + 1 < buckets_.size() && buckets_[i + 1].contour > b.contour) b = buckets_[i + 1];
    buckets_[kept++] = b;
  }
  buckets_.resize(kept);
  stride_ *= 2;
}

void ContourFigure::draw(const std::string& title) {
  if (ticks_ == drawn_ticks_) return;
  drawn_ticks_ = ticks_;
  std::vector<double> t, um;
  t.reserve(buckets_.size());
  um.reserve(buckets_.size());
  for (const Point& b : buckets_) {
    t.push_back(b.time);
    um.push_back(b.contour * 1e3);
  }
  plot::Figure fig;
  fig.title(title);
  fig.xlabel("machine time [s]");
  fig.ylabel("contour error [um]");
  char legend[160];
  const double rms = cutting_ ? std::sqrt(sum_sq_ / static_cast<double>(cutting_)) : 0.0;
  std::snprintf(legend, sizeof legend, "before (the simulate stage runs the original), cutting moves: max %.2f um, RMS %.2f um",
                max_ * 1e3, rms * 1e3);
  // The simulate stage runs the original program: batch's "before" colour (one palette).
  fig.line(std::move(t), std::move(um), plot::role_colour(plot::Role::kBefore), 2, legend);
  char note[200];
  std::snprintf(note, sizeof note, "live, from the simulate stage's telemetry: %llu ticks to t = %.2f s%s",
                static_cast<unsigned long long>(ticks_), now_,
                stride_ > 1 ? " (each point the largest of its stretch of ticks)" : "");
  fig.note(note);
  fig.note("distance of the simulated tool tip to the nominal path; rapids carry none");
  std::filesystem::path part = png_;
  part += ".part";
  fig.save_png(part);
  std::error_code ec;
  std::filesystem::rename(part, png_, ec);
  if (ec) throw std::runtime_error("cannot rename " + part.string() + " to " + png_.string() + ": " + ec.message());
}

}  // namespace gcpipe::dds
