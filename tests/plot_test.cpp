// The plotting helpers: tick choice, colour maps, and a figure whose pixels land where the data
// says.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>

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
  // Plot area as laid out: left 100, right 40 + bar room (24 + 110), top 60, bottom 80.
  const int ax = 100, aw = 800 - 100 - 40 - 134, ay = 60, ah = 600 - 60 - 80;
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
