// PNG output of a rendered figure. Figures are drawn with OpenCV (core, imgproc) and encoded with
// libpng directly: Debian's libopencv_imgcodecs pulls in about 140 shared libraries (GDAL and its
// kin), and loading them cost every gcpipe command about 150 ms of start-up, measured with
// `perf stat gcpipe stages` (180 ms before, see stages/README.md).
#pragma once

#include <filesystem>

namespace cv {
class Mat;
}

namespace gcpipe::plot {

/// Writes an 8-bit BGR (or grey) image as PNG; throws std::runtime_error naming the file.
void write_png(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace gcpipe::plot
