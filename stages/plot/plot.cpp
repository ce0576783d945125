#include "plot.hpp"

#include "png.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace gcpipe::plot {

namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kBlack(0, 0, 0), kGrey(200, 200, 200), kWhite(255, 255, 255);

cv::Size text_size(const std::string& s, double scale, int thick, int* baseline = nullptr) {
  int b = 0;
  cv::Size sz = cv::getTextSize(s, kFont, scale, thick, &b);
  if (baseline) *baseline = b;
  return sz;
}

void put(cv::Mat& img, const std::string& s, cv::Point org, double scale, int thick = 1,
         cv::Scalar colour = kBlack) {
  cv::putText(img, s, org, kFont, scale, colour, thick, cv::LINE_AA);
}

// Text rotated 90 deg counter-clockwise (for the y label): drawn upright, then rotated.
void put_vertical(cv::Mat& img, const std::string& s, cv::Point centre, double scale) {
  int base = 0;
  const cv::Size sz = text_size(s, scale, 1, &base);
  cv::Mat tile(sz.height + base + 4, sz.width + 4, CV_8UC3, kWhite);
  put(tile, s, {2, sz.height + 2}, scale);
  cv::Mat rot;
  cv::rotate(tile, rot, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int x = std::clamp(centre.x - rot.cols / 2, 0, std::max(0, img.cols - rot.cols));
  const int y = std::clamp(centre.y - rot.rows / 2, 0, std::max(0, img.rows - rot.rows));
  rot.copyTo(img(cv::Rect(x, y, rot.cols, rot.rows)));
}

int cv_map(ColourMap m) {
  switch (m) {
    case ColourMap::kViridis: return cv::COLORMAP_VIRIDIS;
    case ColourMap::kTurbo: return cv::COLORMAP_TURBO;
    case ColourMap::kInferno: return cv::COLORMAP_INFERNO;
  }
  return cv::COLORMAP_VIRIDIS;
}

}  // namespace

cv::Scalar colour_at(ColourMap map, double t) {
  static std::array<cv::Mat, 3> luts;
  cv::Mat& lut = luts[std::size_t(map)];
  if (lut.empty()) {
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = std::uint8_t(i);
    cv::applyColorMap(ramp, lut, cv_map(map));
  }
  const int i = std::clamp(int(std::lround(std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * 255)), 0, 255);
  const cv::Vec3b c = lut.at<cv::Vec3b>(0, i);
  return {double(c[0]), double(c[1]), double(c[2])};
}

cv::Scalar palette(int index) {
  static const std::array<cv::Scalar, 10> tab10 = {
      cv::Scalar(180, 119, 31), cv::Scalar(14, 127, 255), cv::Scalar(44, 160, 44),
      cv::Scalar(40, 39, 214),  cv::Scalar(189, 103, 148), cv::Scalar(75, 86, 140),
      cv::Scalar(194, 119, 227), cv::Scalar(127, 127, 127), cv::Scalar(34, 189, 188),
      cv::Scalar(207, 190, 23)};
  return tab10[std::size_t(((index % 10) + 10) % 10)];
}

cv::Scalar role_colour(Role role) {
  switch (role) {
    case Role::kBefore: return {40, 39, 214};       // red
    case Role::kFeedForward: return {14, 127, 255};  // orange
    case Role::kAfter: return {180, 119, 31};        // blue
    case Role::kNominal: return {120, 120, 120};     // grey
  }
  return {0, 0, 0};
}

const char* role_name(Role role) {
  switch (role) {
    case Role::kBefore: return "before";
    case Role::kFeedForward: return "feed-forward";
    case Role::kAfter: return "after";
    case Role::kNominal: return "nominal";
  }
  return "";
}

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return {lo};
  const double raw = (hi - lo) / std::max(1, target);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  // The 1-2-5 step whose tick count comes closest to the target.
  double step = mag;
  double best = 1e300;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    const double miss = std::abs((hi - lo) / (m * mag) - target);
    if (miss < best) best = miss, step = m * mag;
  }
  std::vector<double> t;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step)
    t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  return t;
}

std::string tick_label(double v, double step) {
  int decimals = 0;
  while (decimals < 9 && std::abs(step * std::pow(10.0, decimals) - std::round(step * std::pow(10.0, decimals))) > 1e-6)
    ++decimals;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

Figure::Figure(FigureStyle style) : style_(style) {}

void Figure::limits(double xmin, double xmax, double ymin, double ymax) {
  limits_ = std::array<double, 4>{xmin, xmax, ymin, ymax};
}

void Figure::line(std::vector<double> x, std::vector<double> y, cv::Scalar colour, int thickness,
                  std::string label) {
  series_.push_back({std::move(x), std::move(y), {}, colour, thickness, 0, std::move(label)});
}

void Figure::coloured_line(std::vector<double> x, std::vector<double> y, std::vector<double> value,
                           int thickness) {
  series_.push_back({std::move(x), std::move(y), std::move(value), kBlack, thickness, 0, {}});
}

void Figure::scatter(std::vector<double> x, std::vector<double> y, cv::Scalar colour, int radius,
                     std::string label) {
  series_.push_back({std::move(x), std::move(y), {}, colour, 1, std::max(1, radius), std::move(label)});
}

void Figure::colourbar(std::string label, double vmin, double vmax, ColourMap map) {
  bar_ = Bar{std::move(label), vmin, vmax > vmin ? vmax : vmin + 1.0, map};
}

cv::Point2d Figure::Frame::to_px(double x, double y) const {
  return cv::Point2d(area.x + (x - x0) / (x1 - x0) * area.width, area.y + area.height - (y - y0) / (y1 - y0) * area.height);
}

// Plot area (the colour bar and its labels take room on the right, notes in the top margin) and
// data range: the limits set, else the data's bounding box plus 3 %, widened to equal scales when
// asked.
Figure::Frame Figure::frame() const {
  const FigureStyle& st = style_;
  Frame f;
  const int bar_room = bar_ ? st.colourbar_width + 110 : 0;
  const int top = st.margin_top + notes_height() + legend_rows() * legend_row_height();
  f.area = cv::Rect(st.margin_left, top, st.width - st.margin_left - st.margin_right - bar_room, st.height - top - st.margin_bottom);
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  if (limits_) {
    x0 = (*limits_)[0];
    x1 = (*limits_)[1];
    y0 = y_of((*limits_)[2]);
    y1 = y_of((*limits_)[3]);
  } else {
    for (const auto& s : series_)
      for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
        x0 = std::min(x0, s.x[i]);
        x1 = std::max(x1, s.x[i]);
        y0 = std::min(y0, y_of(s.y[i]));
        y1 = std::max(y1, y_of(s.y[i]));
      }
    if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    const double px = std::max(x1 - x0, 1e-9) * 0.03, py = std::max(y1 - y0, 1e-9) * 0.03;
    x0 -= px, x1 += px, y0 -= py, y1 += py;
  }
  if (!(x1 > x0)) x0 -= 0.5, x1 += 0.5;
  if (!(y1 > y0)) y0 -= 0.5, y1 += 0.5;
  if (equal_) {
    const double sx = f.area.width / (x1 - x0), sy = f.area.height / (y1 - y0);
    if (sx > sy) {
      const double w = f.area.width / sy, c = 0.5 * (x0 + x1);
      x0 = c - 0.5 * w, x1 = c + 0.5 * w;
    } else {
      const double h = f.area.height / sx, c = 0.5 * (y0 + y1);
      y0 = c - 0.5 * h, y1 = c + 0.5 * h;
    }
  }
  f.x0 = x0, f.x1 = x1, f.y0 = y0, f.y1 = y1;
  return f;
}

int Figure::draw_grid(cv::Mat& img, const Frame& f) const {
  const FigureStyle& st = style_;
  const double fs = st.font_scale;
  const cv::Rect& area = f.area;
  const auto xt = nice_ticks(f.x0, f.x1, std::max(3, area.width / 140));
  const auto yt = nice_ticks(f.y0, f.y1, std::max(3, area.height / 90));
  const double xstep = xt.size() > 1 ? xt[1] - xt[0] : 1.0, ystep = yt.size() > 1 ? yt[1] - yt[0] : 1.0;
  for (double v : xt) {
    const int px = int(std::lround(f.to_px(v, f.y0).x));
    if (st.grid) cv::line(img, {px, area.y}, {px, area.y + area.height}, kGrey, 1, cv::LINE_AA);
    cv::line(img, {px, area.y + area.height}, {px, area.y + area.height + 6}, kBlack, 1);
    const std::string s = tick_label(v, xstep);
    const cv::Size sz = text_size(s, fs, 1);
    put(img, s, {px - sz.width / 2, area.y + area.height + 10 + sz.height}, fs);
  }
  int widest_ytick = 0;
  if (log_floor_ > 0) {
    draw_log_grid(img, f, widest_ytick);
    return widest_ytick;
  }
  for (double v : yt) {
    const int py = int(std::lround(f.to_px(f.x0, v).y));
    if (st.grid) cv::line(img, {area.x, py}, {area.x + area.width, py}, kGrey, 1, cv::LINE_AA);
    cv::line(img, {area.x - 6, py}, {area.x, py}, kBlack, 1);
    const std::string s = tick_label(v, ystep);
    const cv::Size sz = text_size(s, fs, 1);
    widest_ytick = std::max(widest_ytick, sz.width);
    put(img, s, {area.x - 10 - sz.width, py + sz.height / 2}, fs);
  }
  return widest_ytick;
}

double Figure::y_of(double y) const {
  return log_floor_ > 0 ? std::log10(std::max(y, log_floor_)) : y;
}

// Log y ticks: every 1, 2, 5 x 10^k within two decades, else every decade (with light lines at
// 2 and 5 between); labels in the data's units.
void Figure::draw_log_grid(cv::Mat& img, const Frame& f, int& widest_ytick) const {
  const double fs = style_.font_scale;
  const cv::Rect& area = f.area;
  const bool fine = f.y1 - f.y0 <= 2.0;
  for (int e = static_cast<int>(std::floor(f.y0)); e <= static_cast<int>(std::ceil(f.y1)); ++e)
    for (double m : {1.0, 2.0, 5.0}) {
      const double ly = e + std::log10(m);
      if (ly < f.y0 || ly > f.y1) continue;
      const int py = int(std::lround(f.to_px(f.x0, ly).y));
      const bool major = m == 1.0 || fine;
      if (style_.grid) cv::line(img, {area.x, py}, {area.x + area.width, py}, major ? kGrey : cv::Scalar(232, 232, 232), 1, cv::LINE_AA);
      if (!major) continue;
      cv::line(img, {area.x - 6, py}, {area.x, py}, kBlack, 1);
      const double v = m * std::pow(10.0, e);
      char small[32];
      std::snprintf(small, sizeof small, "%g", v);
      const std::string label = v < 1e-3 || v >= 1e5 ? std::string(small) : tick_label(v, v);
      const cv::Size sz = text_size(label, fs, 1);
      widest_ytick = std::max(widest_ytick, sz.width);
      put(img, label, {area.x - 10 - sz.width, py + sz.height / 2}, fs);
    }
}

int Figure::notes_height() const {
  return int(notes_.size()) * int(std::lround(28 * style_.font_scale / 0.6));
}

int Figure::legend_rows() const {
  return int(std::count_if(series_.begin(), series_.end(), [](const Series& s) { return !s.label.empty(); }));
}

int Figure::legend_row_height() const {
  return text_size("Ag", style_.font_scale, 1).height + 12;
}

// The points of a line series worth drawing. A time series (x never decreasing, one colour) with
// many more points than pixel columns keeps, per column, its first, lowest, highest and last point
// in their order: the drawn band is the same, with a few thousand anti-aliased segments instead of
// tens of thousands (the following-error figures of a long program were most of batch's drawing).
std::vector<std::size_t> Figure::drawn_points(const Series& s, const Frame& f) const {
  const std::size_t n = std::min(s.x.size(), s.y.size());
  std::vector<std::size_t> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = i;
  const auto columns = static_cast<std::size_t>(std::max(1, f.area.width));
  if (n <= 4 * columns || !s.value.empty() || !std::is_sorted(s.x.begin(), s.x.begin() + static_cast<std::ptrdiff_t>(n)))
    return all;
  std::vector<std::size_t> keep;
  keep.reserve(4 * columns + 4);
  std::size_t i = 0;
  while (i < n) {
    const long col = std::lround(std::floor(f.to_px(s.x[i], f.y0).x));
    std::size_t first = i, lo = i, hi = i, last = i;
    for (; i < n && std::lround(std::floor(f.to_px(s.x[i], f.y0).x)) == col; ++i) {
      if (s.y[i] < s.y[lo]) lo = i;
      if (s.y[i] > s.y[hi]) hi = i;
      last = i;
    }
    std::size_t pts[4] = {first, std::min(lo, hi), std::max(lo, hi), last};
    for (std::size_t p : pts)
      if (keep.empty() || keep.back() != p) keep.push_back(p);
  }
  return keep;
}

// Data, clipped to the plot area.
void Figure::draw_series(cv::Mat& img, const Frame& f) const {
  const cv::Rect& area = f.area;
  cv::Mat plot = img(area);
  auto local = [&](double x, double y) {
    const cv::Point2d p = f.to_px(x, y_of(y));
    // Sub-pixel precision with 4 fractional bits keeps dense paths smooth.
    return cv::Point(int(std::lround((p.x - area.x) * 16)), int(std::lround((p.y - area.y) * 16)));
  };
  for (const auto& s : series_) {
    const std::size_t n = std::min(s.x.size(), s.y.size());
    if (s.marker_radius > 0) {
      for (std::size_t i = 0; i < n; ++i)
        cv::circle(plot, local(s.x[i], s.y[i]), s.marker_radius * 16, s.colour, cv::FILLED, cv::LINE_AA, 4);
      continue;
    }
    const std::vector<std::size_t> keep = drawn_points(s, f);
    for (std::size_t k = 0; k + 1 < keep.size(); ++k) {
      const std::size_t i = keep[k], j = keep[k + 1];
      cv::Scalar c = s.colour;
      if (!s.value.empty() && bar_) {
        const double v = i < s.value.size() ? s.value[i] : s.value.back();
        c = colour_at(bar_->map, (v - bar_->vmin) / (bar_->vmax - bar_->vmin));
      }
      cv::line(plot, local(s.x[i], s.y[i]), local(s.x[j], s.y[j]), c, s.thickness, cv::LINE_AA, 4);
    }
  }
  cv::rectangle(img, area, kBlack, 1);
}

// Title, axis labels, and the notes: small lines under the title, in the top margin.
void Figure::draw_labels(cv::Mat& img, const Frame& f, int widest_ytick) const {
  const FigureStyle& st = style_;
  const double fs = st.font_scale;
  const cv::Rect& area = f.area;
  if (!title_.empty()) {
    const cv::Size sz = text_size(title_, fs * 1.4, 2);
    put(img, title_, {std::max(4, area.x + area.width / 2 - sz.width / 2), st.margin_top / 2 + sz.height / 2}, fs * 1.4, 2);
  }
  if (!xlabel_.empty()) {
    const cv::Size sz = text_size(xlabel_, fs * 1.15, 1);
    put(img, xlabel_, {area.x + area.width / 2 - sz.width / 2, st.height - 18}, fs * 1.15);
  }
  if (!ylabel_.empty())
    put_vertical(img, ylabel_, {std::max(14, area.x - widest_ytick - 32), area.y + area.height / 2}, fs * 1.15);
  int ny = st.margin_top / 2 + int(text_size("Ag", fs * 1.4, 2).height * 0.5) + 8;
  for (const auto& n : notes_) {
    const cv::Size sz = text_size(n, fs * 0.9, 1);
    ny += sz.height + 8;
    put(img, n, {std::max(4, area.x + area.width / 2 - sz.width / 2), ny}, fs * 0.9);
  }
}

// Legend, one entry a row in the margin above the plot area (reserved by frame()): it never
// covers data.
void Figure::draw_legend(cv::Mat& img, const Frame& f) const {
  const double fs = style_.font_scale;
  const cv::Rect& area = f.area;
  std::vector<const Series*> labelled;
  for (const auto& s : series_)
    if (!s.label.empty()) labelled.push_back(&s);
  if (labelled.empty()) return;
  const int h = text_size("Ag", fs, 1).height, row = legend_row_height();
  const cv::Rect box(area.x, area.y - int(labelled.size()) * row - 4, area.width, int(labelled.size()) * row);
  for (std::size_t i = 0; i < labelled.size(); ++i) {
    const int cy = box.y + int(i) * row + row / 2;
    if (labelled[i]->marker_radius > 0)
      cv::circle(img, {box.x + 22, cy}, labelled[i]->marker_radius, labelled[i]->colour, cv::FILLED, cv::LINE_AA);
    else
      cv::line(img, {box.x + 8, cy}, {box.x + 38, cy}, labelled[i]->colour, labelled[i]->thickness, cv::LINE_AA);
    put(img, labelled[i]->label, {box.x + 48, cy + h / 2}, fs);
  }
}

void Figure::draw_colourbar(cv::Mat& img, const Frame& f) const {
  if (!bar_) return;
  const FigureStyle& st = style_;
  const double fs = st.font_scale;
  const int bx = f.area.x + f.area.width + 30, by = f.area.y, bh = f.area.height;
  for (int i = 0; i < bh; ++i) {
    const double t = 1.0 - double(i) / std::max(1, bh - 1);
    cv::line(img, {bx, by + i}, {bx + st.colourbar_width, by + i}, colour_at(bar_->map, t), 1);
  }
  cv::rectangle(img, {bx, by}, {bx + st.colourbar_width, by + bh}, kBlack, 1);
  const auto bt = nice_ticks(bar_->vmin, bar_->vmax, 6);
  const double bstep = bt.size() > 1 ? bt[1] - bt[0] : 1.0;
  for (double v : bt) {
    const int py = by + int(std::lround((1.0 - (v - bar_->vmin) / (bar_->vmax - bar_->vmin)) * (bh - 1)));
    cv::line(img, {bx + st.colourbar_width, py}, {bx + st.colourbar_width + 5, py}, kBlack, 1);
    const std::string s = tick_label(v, bstep);
    const cv::Size sz = text_size(s, fs, 1);
    put(img, s, {bx + st.colourbar_width + 8, py + sz.height / 2}, fs);
  }
  put_vertical(img, bar_->label, {std::min(st.width - 14, bx + st.colourbar_width + 80), by + bh / 2}, fs * 1.15);
}

cv::Mat Figure::render() const {
  cv::Mat img(style_.height, style_.width, CV_8UC3, kWhite);
  const Frame f = frame();
  const int widest_ytick = draw_grid(img, f);
  draw_series(img, f);
  draw_labels(img, f, widest_ytick);
  draw_legend(img, f);
  draw_colourbar(img, f);
  return img;
}

void Figure::save_png(const std::filesystem::path& path) const {
  write_png(path, render());
}

}  // namespace gcpipe::plot
