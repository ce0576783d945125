#include "program_stream.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

#include "gcpipe/line_reader.hpp"

namespace gcpipe::cli {

InputFile::InputFile(const std::string& path) : name_(path) {
  if (path == "-") {
    fd_ = 0;
    name_ = "<stdin>";
    return;
  }
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw std::runtime_error(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) == 0) {
    if (S_ISDIR(st.st_mode)) {
      ::close(fd_);
      throw std::runtime_error(path + ": is a directory, expected a G-code file");
    }
    if (S_ISREG(st.st_mode)) size_ = static_cast<std::uint64_t>(st.st_size);
  }
}

InputFile::~InputFile() {
  if (fd_ > 0) ::close(fd_);
}

std::function<bool(const Diagnostic&)> print_diagnostics(std::uint64_t& errors) {
  return [&errors](const Diagnostic& d) {
    if (d.severity == Severity::kError) ++errors;
    std::fprintf(stderr, "%s\n", format(d).c_str());
    return true;
  };
}

bool stream_program(InputFile& in, Parser& parser, const LineSink& sink, bool progress,
                    std::string& error) {
  const std::size_t max_line = parser.options().max_line_length;
  LineReader reader(in.fd(), max_line);
  // Strict mode stops at the first error; the parser's sink says so by returning false.
  bool strict_stop = false;
  const ParseSink parse_sink{
      [&](const ResolvedBlock& b) { return sink.block(b); },
      [&](const Diagnostic& d) {
        if (!sink.diagnostic(d)) return false;
        if (d.severity == Severity::kError && parser.options().strict) strict_stop = true;
        return !strict_stop;
      }};
  std::string_view line;
  bool overlong = false;
  std::size_t full = 0;
  using clock = std::chrono::steady_clock;
  auto next_report = clock::now() + std::chrono::seconds(1);
  const auto t0 = clock::now();
  bool shown = false;
  while (reader.next(line, overlong, full)) {
    if (!parser.feed(line, parse_sink, overlong ? full : 0)) {
      if (strict_stop) error = "stopped at the first error (parse.strict is on)";
      return false;
    }
    if (progress && (parser.summary().lines_read & 0xfff) == 0 && clock::now() > next_report) {
      next_report += std::chrono::seconds(1);
      const double s = std::chrono::duration<double>(clock::now() - t0).count();
      const double mb = static_cast<double>(reader.bytes_read()) / 1e6;
      if (in.size() > 0)
        std::fprintf(stderr, "\r%s: %5.1f %%  %.0f MB  %.0f MB/s  %llu lines   ", in.name().c_str(),
                     100.0 * static_cast<double>(reader.bytes_read()) / static_cast<double>(in.size()), mb, mb / s,
                     static_cast<unsigned long long>(parser.summary().lines_read));
      else
        std::fprintf(stderr, "\r%s: %.0f MB  %.0f MB/s  %llu lines   ", in.name().c_str(), mb, mb / s,
                     static_cast<unsigned long long>(parser.summary().lines_read));
      shown = true;
    }
  }
  if (shown) std::fprintf(stderr, "\n");
  if (!reader.error().empty()) {
    error = in.name() + ": read error: " + reader.error();
    return false;
  }
  // What waited for more input (a call to a subroutine never defined, an unclosed loop).
  if (!parser.finish(parse_sink)) {
    if (strict_stop) error = "stopped at the first error (parse.strict is on)";
    return false;
  }
  return true;
}

PipelineConfig load_config_option(const std::string& path_or_empty) {
  if (!path_or_empty.empty()) return load_pipeline_config(path_or_empty);
  auto def = default_pipeline_config();
  if (!std::filesystem::exists(def))
    throw std::runtime_error("no --config given and the default " + def.string() +
                             " does not exist: pass --config pipeline_configs/<name>.yaml");
  return load_pipeline_config(def);
}

OutputFile::OutputFile(const std::string& path) : path_(path) {
  if (path == "-") {
    f_ = stdout;
    return;
  }
  f_ = std::fopen(path.c_str(), "wb");
  if (f_ == nullptr) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
}

OutputFile::~OutputFile() {
  if (f_ != nullptr && f_ != stdout) std::fclose(f_);
}

void OutputFile::write(std::string& buffer, bool force) {
  if (!force && buffer.size() < (1u << 20)) return;
  if (!buffer.empty() && std::fwrite(buffer.data(), 1, buffer.size(), f_) != buffer.size())
    throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
  buffer.clear();
}

void OutputFile::close() {
  if (f_ == nullptr) return;
  if (std::fflush(f_) != 0) throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
  if (f_ != stdout) std::fclose(f_);
  f_ = nullptr;
}

}  // namespace gcpipe::cli
