#include "png.hpp"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace gcpipe::plot {

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  *static_cast<std::string*>(png_get_error_ptr(png)) = message;
  png_longjmp(png, 1);
}

}  // namespace

void write_png(const std::filesystem::path& path, const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1))
    throw std::runtime_error("cannot write PNG '" + path.string() + "': not an 8-bit BGR or grey image");
  std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.string().c_str(), "wb"));
  if (!file) throw std::runtime_error("cannot write PNG '" + path.string() + "': " + std::strerror(errno));
  std::string error;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, on_png_error, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr) {
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error("cannot write PNG '" + path.string() + "': out of memory");
  }
  // libpng reports errors by longjmp: nothing with a destructor may be created below this point.
  const cv::Mat* rows = &image;
  std::vector<png_bytep> row_pointers(static_cast<std::size_t>(image.rows));
  for (int r = 0; r < image.rows; ++r) row_pointers[static_cast<std::size_t>(r)] = const_cast<png_bytep>(rows->ptr<png_byte>(r));
  if (setjmp(png_jmpbuf(png)) == 0) {
    png_init_io(png, file.get());
    png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows), 8,
                 image.channels() == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 3);  // figures compress well already; level 9 only costs time
    png_write_info(png, info);
    if (image.channels() == 3) png_set_bgr(png);  // OpenCV keeps B G R
    png_write_image(png, row_pointers.data());
    png_write_end(png, nullptr);
  }
  png_destroy_write_struct(&png, &info);
  if (!error.empty()) throw std::runtime_error("cannot write PNG '" + path.string() + "': " + error);
  if (std::fflush(file.get()) != 0) throw std::runtime_error("cannot write PNG '" + path.string() + "': " + std::strerror(errno));
}

}  // namespace gcpipe::plot
