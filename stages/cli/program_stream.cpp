#include "program_stream.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>


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

PipelineConfig load_config_option(const std::string& path_or_empty, const std::string& tool_table) {
  std::filesystem::path path = path_or_empty;
  if (path.empty()) {
    path = default_pipeline_config();
    if (!std::filesystem::exists(path))
      throw std::runtime_error("no --config given and the default " + path.string() +
                               " does not exist: pass --config pipeline_configs/<name>.yaml");
  }
  PipelineConfig pc = load_pipeline_config(path);
  if (!tool_table.empty()) merge_tool_table(pc.machine, tool_table);
  return pc;
}

}  // namespace gcpipe::cli
