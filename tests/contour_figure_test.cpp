// The live figure of `gcpipe monitor --plot`: bounded memory whatever the program's length, no
// peak lost to the thinning, and a PNG under its final name only.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include <unistd.h>

#include "contour_figure.hpp"

namespace {

namespace fs = std::filesystem;

TEST(ContourFigure, KeepsEveryPeakInBoundedPointsAndWritesAWholePng) {
  const fs::path png = fs::temp_directory_path() / ("gcpipe_contour_figure_" + std::to_string(::getpid()) + ".png");
  gcpipe::dds::ContourFigure figure(png, 64);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(0.001, 0.002);
  const std::size_t ticks = 200000, peak_at = 123457;
  for (std::size_t i = 0; i < ticks; ++i) {
    const double contour = i == peak_at ? 0.5 : (i % 1000 < 100 ? 0.0 : noise(rng));  // rapids: 0
    figure.add(static_cast<double>(i) * 1e-3, contour);
  }
  EXPECT_EQ(figure.ticks(), ticks);
  EXPECT_LE(figure.points().size(), 64u);
  EXPECT_GE(figure.points().size(), 32u);  // thinned by halves: never below half the capacity
  const auto top = std::max_element(figure.points().begin(), figure.points().end(),
                                    [](const auto& a, const auto& b) { return a.contour < b.contour; });
  EXPECT_DOUBLE_EQ(top->contour, 0.5);
  EXPECT_DOUBLE_EQ(top->time, static_cast<double>(peak_at) * 1e-3);
  EXPECT_DOUBLE_EQ(figure.max_mm(), 0.5);
  EXPECT_TRUE(std::is_sorted(figure.points().begin(), figure.points().end(),
                             [](const auto& a, const auto& b) { return a.time < b.time; }));
  figure.draw("test");
  std::ifstream f(png, std::ios::binary);
  const std::string head((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(head.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_FALSE(fs::exists(png.string() + ".part"));
  fs::remove(png);
}

}  // namespace
