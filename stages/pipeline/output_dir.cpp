#include "output_dir.hpp"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "gcpipe/stop.hpp"

namespace gcpipe::pipeline {

namespace fs = std::filesystem;

AtomicFile::AtomicFile(const std::string& path) : path_(path) {
  if (path == "-") {
    f_ = stdout;
    return;
  }
  // A device, pipe or socket (-o /dev/null, a named pipe to another program) is written in place:
  // renaming a .part file over it would replace /dev/null with a regular file, as it once did.
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!ec && fs::exists(status) && !fs::is_regular_file(status) && !fs::is_directory(status)) {
    f_ = std::fopen(path.c_str(), "wb");
    if (f_ == nullptr) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
    direct_ = true;
    return;
  }
  // A folder cannot be replaced by a file: say so now, not after the whole run at the rename,
  // which left FOLDER.part beside it (`parse -o /tmp` wrote /tmp.part).
  if (!ec && fs::is_directory(status))
    throw std::runtime_error(path + ": is a folder: give a file name (e.g. " + (fs::path(path) / "out.txt").string() + ")");
  part_ = path + ".part";
  f_ = std::fopen(part_.c_str(), "wb");
  if (f_ == nullptr) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (f_ == nullptr || f_ == stdout) return;
  std::fclose(f_);
  if (!direct_) std::remove(part_.c_str());
}

void AtomicFile::write(std::string& buffer, bool force) {
  if (!force && buffer.size() < (1u << 20)) return;
  if (f_ == nullptr) throw std::logic_error(path_ + ": written after commit");
  if (!buffer.empty() && std::fwrite(buffer.data(), 1, buffer.size(), f_) != buffer.size())
    throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
  buffer.clear();
}

void AtomicFile::commit() {
  if (f_ == nullptr) return;
  const bool ok = std::fflush(f_) == 0;
  if (f_ == stdout) {
    f_ = nullptr;
    if (!ok) throw std::runtime_error("standard output: write failed: " + std::string(std::strerror(errno)));
    return;
  }
  const bool closed = std::fclose(f_) == 0;
  f_ = nullptr;
  if (!ok || !closed) {
    if (!direct_) std::remove(part_.c_str());
    throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
  }
  if (direct_) return;
  if (std::rename(part_.c_str(), path_.c_str()) != 0) {
    const int err = errno;
    std::remove(part_.c_str());  // a file that never gets its name is not left behind
    throw std::runtime_error(path_ + ": cannot rename " + part_ + ": " + std::strerror(err));
  }
}

void write_file_atomically(const fs::path& path, std::string text) {
  AtomicFile f(path.string());
  f.write(text, true);
  f.commit();
}

namespace {

void remove_parts(const fs::path& dir) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".part") fs::remove(it->path(), ec);
}

}  // namespace

void prepare_output_dir(const fs::path& dir, const std::vector<std::string>& names) {
  std::error_code ec;
  fs::create_directories(dir / "plots", ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create the output folder: " + ec.message());
  for (const auto& n : names) {
    fs::remove(dir / n, ec);
    if (ec) throw std::runtime_error((dir / n).string() + ": cannot remove the file of an earlier run: " + ec.message());
  }
  remove_parts(dir);
  remove_parts(dir / "plots");
}

namespace {

extern "C" void on_stop_signal(int sig) {
  if (gcpipe::request_stop(sig) != 0) std::_Exit(128 + sig);  // the second Ctrl-C does not wait
}

}  // namespace

void install_stop_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool stop_requested() { return gcpipe::stop_requested(); }
int stop_signal() { return gcpipe::stop_signal(); }

}  // namespace gcpipe::pipeline
