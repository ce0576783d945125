// Stage helper `plot`: 2-D line plots on a cv::Mat, written as PNG. For the error and tool-path
// figures of every stage: data-coordinate polylines (plain or coloured by a value), scatter marks,
// axes with "nice" ticks, labels with units, a legend and a colour bar.
//
// Retained mode: add data and decorations in any order, then render()/save_png(). Limits default
// to the data's bounding box; equal_aspect keeps 1 mm = 1 mm on both axes (tool paths).
// Hershey fonts are ASCII only: write "um", "deg" in labels.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace gcpipe::plot {

/// Colour maps for value-coloured lines and the colour bar (OpenCV's tables).
enum class ColourMap { kViridis, kTurbo, kInferno };

/// BGR colour for t in [0, 1] (clamped) of the map.
cv::Scalar colour_at(ColourMap map, double t);

/// Default line colours (matplotlib's "tab10"), BGR.
cv::Scalar palette(int index);

/// What a curve of a compensation figure stands for. Each has one colour in every figure (batch's,
/// `monitor --plot`'s), so that red is always the original and blue always the compensation.
enum class Role { kBefore, kFeedForward, kAfter, kNominal };
/// BGR: before red, feed-forward orange, after blue, nominal grey.
cv::Scalar role_colour(Role role);
/// "before", "feed-forward", "after", "nominal".
const char* role_name(Role role);

/// "Nice" tick positions covering [lo, hi]: steps of 1, 2 or 5 x 10^k, about `target` ticks.
std::vector<double> nice_ticks(double lo, double hi, int target = 6);

/// Tick label without trailing zeros: 0.5, 10, -2.25.
std::string tick_label(double v, double step);

struct FigureStyle {
  int width = 1400;            //!< [px]
  int height = 900;            //!< [px]
  double font_scale = 0.6;     //!< Hershey simplex scale for ticks; titles 1.4x
  int margin_left = 100, margin_right = 40, margin_top = 60, margin_bottom = 80;  //!< [px]
                               //!< (margin_top grows by one line per note and per legend entry:
                               //!< the legend stands above the plot area, never on the data)
  int colourbar_width = 24;    //!< [px]; space is reserved only when a colour bar is set
  bool grid = true;            //!< light grid lines at the ticks
};

class Figure {
 public:
  explicit Figure(FigureStyle style = {});

  void title(std::string text) { title_ = std::move(text); }
  void xlabel(std::string text) { xlabel_ = std::move(text); }
  void ylabel(std::string text) { ylabel_ = std::move(text); }
  /// Fixes the data range shown; otherwise the data's bounding box plus 3 %.
  void limits(double xmin, double xmax, double ymin, double ymax);
  /// Same scale on both axes (the shown range grows to fill the plot area).
  void equal_aspect(bool on) { equal_ = on; }
  /// Logarithmic y axis (ticks at 1, 2, 5 x 10^k, or at decades over a wide range); y values
  /// below `floor` (zeros included) are drawn at it. `floor` <= 0 turns it off.
  void log_y(double floor) { log_floor_ = floor; }

  /// A polyline in data coordinates; `label` non-empty adds a legend entry.
  void line(std::vector<double> x, std::vector<double> y, cv::Scalar colour, int thickness = 2,
            std::string label = {});
  /// A polyline whose segment i (from point i to i+1) is coloured by value[i] through the colour
  /// bar's map and range (set colourbar() before render()).
  void coloured_line(std::vector<double> x, std::vector<double> y, std::vector<double> value,
                     int thickness = 2);
  /// Markers (filled circles of `radius` px).
  void scatter(std::vector<double> x, std::vector<double> y, cv::Scalar colour, int radius = 3,
               std::string label = {});
  /// Colour bar at the right for coloured_line values in [vmin, vmax].
  void colourbar(std::string label, double vmin, double vmax, ColourMap map = ColourMap::kViridis);
  /// A line of smaller text under the title (for measured figures); the plot area shrinks.
  void note(std::string text) { notes_.push_back(std::move(text)); }
  /// Number of pixels the plot area will have, for sizing a figure to its data's aspect.
  static int area_width(const FigureStyle& s, bool colourbar) {
    return s.width - s.margin_left - s.margin_right - (colourbar ? s.colourbar_width + 110 : 0);
  }

  /// Draws everything into a new image (BGR, 8 bit).
  cv::Mat render() const;
  /// render() and write a PNG; throws std::runtime_error naming the path when it fails.
  void save_png(const std::filesystem::path& path) const;

 private:
  struct Series {
    std::vector<double> x, y, value;
    cv::Scalar colour;
    int thickness = 2;
    int marker_radius = 0;  // > 0: scatter
    std::string label;
  };
  struct Bar {
    std::string label;
    double vmin = 0, vmax = 1;
    ColourMap map = ColourMap::kViridis;
  };
  /// The plot area in pixels and the data range it shows.
  struct Frame {
    cv::Rect area;
    double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    cv::Point2d to_px(double x, double y) const;
  };
  // The steps of render(), in drawing order.
  Frame frame() const;
  int draw_grid(cv::Mat& img, const Frame& f) const;  //!< returns the widest y tick label [px]
  void draw_series(cv::Mat& img, const Frame& f) const;
  std::vector<std::size_t> drawn_points(const Series& s, const Frame& f) const;
  void draw_labels(cv::Mat& img, const Frame& f, int widest_ytick) const;
  void draw_legend(cv::Mat& img, const Frame& f) const;
  void draw_colourbar(cv::Mat& img, const Frame& f) const;
  void draw_log_grid(cv::Mat& img, const Frame& f, int& widest_ytick) const;
  double y_of(double y) const;         //!< y as drawn: log10 on a log axis
  int legend_rows() const;
  int legend_row_height() const;
  int notes_height() const;
  FigureStyle style_;
  std::string title_, xlabel_, ylabel_;
  std::optional<std::array<double, 4>> limits_;
  bool equal_ = false;
  double log_floor_ = 0;  // > 0: log y axis
  std::vector<Series> series_;
  std::optional<Bar> bar_;
  std::vector<std::string> notes_;
};

}  // namespace gcpipe::plot
