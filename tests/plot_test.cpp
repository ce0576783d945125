// The plotting helpers: tick choice, colour maps, and a figure whose pixels land where the data
// says.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "plot.hpp"

using namespace gcpipe::plot;

TEST(PlotTicks, NiceStepsCoverTheRange) {
  auto t = nice_ticks(0.0, 10.0, 5);
  ASSERT_GE(t.size(), 5u);
  EXPECT_DOUBLE_EQ(t.front(), 0.0);
  EXPECT_DOUBLE_EQ(t.back(), 10.0);
  EXPECT_DOUBLE_EQ(t[1] - t[0], 2.0);
  t = nice_ticks(-0.013, 0.027, 4);
  EXPECT_DOUBLE_EQ(t[1] - t[0], 0.01);
  EXPECT_GE(t.front(), -0.013);
  EXPECT_LE(t.back(), 0.027 + 1e-15);
  EXPECT_EQ(tick_label(0.25, 0.05), "0.25");
  EXPECT_EQ(tick_label(120, 20), "120");
  EXPECT_EQ(tick_label(-1.5, 0.5), "-1.5");
}

TEST(PlotColour, MapsRunFromDarkToBright) {
  const auto lo = colour_at(ColourMap::kViridis, 0.0), hi = colour_at(ColourMap::kViridis, 1.0);
  EXPECT_LT(lo[0] + lo[1] + lo[2], hi[0] + hi[1] + hi[2]);
  EXPECT_EQ(colour_at(ColourMap::kTurbo, -5.0), colour_at(ColourMap::kTurbo, 0.0));  // clamped
}

TEST(PlotFigure, DrawsDataInDataCoordinatesAndWritesPng) {
  FigureStyle st;
  st.width = 800;
  st.height = 600;
  st.grid = false;
  Figure f(st);
  f.title("test: y = x");
  f.xlabel("x [mm]");
  f.ylabel("y [um]");
  f.limits(0, 10, 0, 10);
  f.line({0, 10}, {0, 10}, cv::Scalar(0, 0, 255), 3, "diagonal");
  f.coloured_line({0, 10}, {5, 5}, {0.0}, 3);
  f.colourbar("value [deg]", 0, 1, ColourMap::kViridis);
  const cv::Mat img = f.render();
  ASSERT_EQ(img.cols, 800);
  ASSERT_EQ(img.rows, 600);
  // Plot area as laid out: left 100, right 40 + bar room (24 + 110), top 60 and the legend's one
  // row above the plot area (text height + 12), bottom 80.
  const int legend = cv::getTextSize("Ag", cv::FONT_HERSHEY_SIMPLEX, 0.6, 1, nullptr).height + 12;
  const int ax = 100, aw = 800 - 100 - 40 - 134, ay = 60 + legend, ah = 600 - ay - 80;
  auto px = [&](double x, double y) {
    return cv::Point(int(std::lround(ax + x / 10 * aw)), int(std::lround(ay + ah - y / 10 * ah)));
  };
  const cv::Vec3b mid = img.at<cv::Vec3b>(px(2.5, 2.5));
  EXPECT_GT(mid[2], 200);  // red diagonal
  EXPECT_LT(mid[0], 80);
  const cv::Vec3b flat = img.at<cv::Vec3b>(px(7.5, 5));
  const auto v0 = colour_at(ColourMap::kViridis, 0.0);
  EXPECT_NEAR(flat[0], v0[0], 40);  // coloured by value 0
  EXPECT_NEAR(flat[1], v0[1], 40);
  const cv::Vec3b empty = img.at<cv::Vec3b>(px(8, 2));
  EXPECT_EQ(empty, cv::Vec3b(255, 255, 255));
  const auto out = std::filesystem::path(GCPIPE_BINARY_DIR) / "plot_test.png";
  f.save_png(out);
  const cv::Mat back = cv::imread(out.string());
  EXPECT_EQ(back.cols, 800);
  EXPECT_THROW(f.save_png("/nonexistent-dir/x.png"), std::runtime_error);
}

// The legend stands above the plot area: data in the corner where it used to be drawn (top right,
// inside the plot) stays visible (issue 33 item 5: legends never cover data).
TEST(PlotFigure, TheLegendNeverCoversData) {
  FigureStyle st;
  st.width = 800;
  st.height = 600;
  st.grid = false;
  Figure f(st);
  f.limits(0, 10, 0, 10);
  f.line({0, 10}, {10, 10}, cv::Scalar(0, 0, 255), 5, "a long label that used to sit on the top right corner");
  f.line({0, 10}, {9.5, 9.5}, cv::Scalar(255, 0, 0), 5, "and a second one");
  const cv::Mat img = f.render();
  const int legend = 2 * (cv::getTextSize("Ag", cv::FONT_HERSHEY_SIMPLEX, 0.6, 1, nullptr).height + 12);
  const int ax = 100, aw = 800 - 100 - 40, ay = 60 + legend, ah = 600 - ay - 80;
  const cv::Vec3b blue = img.at<cv::Vec3b>(cv::Point(ax + aw * 9 / 10, int(std::lround(ay + ah * 0.05))));
  EXPECT_GT(blue[0], 200) << "the second line, under where the legend box was";
  EXPECT_LT(blue[2], 80);
}

// A log y axis puts each decade the same height apart, and values below its floor on the floor.
TEST(PlotFigure, LogAxisSpacesDecadesEvenly) {
  FigureStyle st;
  st.width = 800;
  st.height = 600;
  st.grid = false;
  Figure f(st);
  f.limits(0, 10, 0.01, 100);
  f.log_y(0.01);
  f.scatter({2.5, 5, 7.5, 9}, {0.1, 1, 10, 0}, cv::Scalar(0, 0, 255), 4);
  const cv::Mat img = f.render();
  const int ax = 100, aw = 800 - 100 - 40, ay = 60, ah = 600 - 60 - 80;
  auto py = [&](double decades_above_floor) { return int(std::lround(ay + ah - decades_above_floor / 4 * ah)); };
  for (auto [x, d] : {std::pair{2.5, 1.0}, {5.0, 2.0}, {7.5, 3.0}, {9.0, 0.0}}) {
    const cv::Point p(int(std::lround(ax + x / 10 * aw)), std::min(py(d), ay + ah - 2));
    EXPECT_GT(img.at<cv::Vec3b>(p)[2], 200) << "x " << x << ": the mark " << d << " decades above the floor";
  }
}
