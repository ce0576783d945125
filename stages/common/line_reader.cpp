#include "gcpipe/line_reader.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "gcpipe/stop.hpp"

namespace gcpipe {

namespace {
constexpr std::size_t kChunk = 1 << 20;  // 1 MiB reads: large enough that syscalls do not show
}

LineReader::LineReader(int fd, std::size_t max_line) : fd_(fd), max_line_(max_line) {
  buf_.resize(kChunk + max_line_ + 2);
}

bool LineReader::fill() {
  // Keep the unread tail, then read behind it.
  if (begin_ > 0) {
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  if (eof_ || end_ == buf_.size()) return false;
  // Polled once a MiB: a line without end (/dev/zero) is read here and never returns to the
  // caller's per-line check, so a stop must end the input here too.
  if (stop_requested()) {
    eof_ = true;
    return false;
  }
  for (;;) {
    ssize_t n = ::read(fd_, buf_.data() + end_, buf_.size() - end_);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      error_ = std::strerror(errno);
      eof_ = true;
      return false;
    }
    if (n == 0) {
      eof_ = true;
      return false;
    }
    end_ += static_cast<std::size_t>(n);
    bytes_ += static_cast<std::uint64_t>(n);
    return true;
  }
}

bool LineReader::next(std::string_view& line, bool& overlong, std::size_t& full_length) {
  overlong = false;
  for (;;) {
    const char* start = buf_.data() + begin_;
    const std::size_t avail = end_ - begin_;
    const char* nl = static_cast<const char*>(std::memchr(start, '\n', avail));
    if (nl != nullptr) {
      std::size_t len = static_cast<std::size_t>(nl - start);
      begin_ += len + 1;
      full_length = len;
      if (len > 0 && start[len - 1] == '\r') --len, --full_length;
      if (len > max_line_) {
        overlong = true;
        len = max_line_;
      }
      line = std::string_view(start, len);
      return true;
    }
    if (avail > max_line_ + 1) {
      // No terminator within the allowed length: report the head, then drop bytes until '\n'.
      long_.assign(start, max_line_);
      std::size_t skipped = avail;
      char last = start[avail - 1];  // to drop a '\r' before the '\n', as the short path does
      begin_ = end_;
      for (;;) {
        if (!fill()) break;
        const char* s = buf_.data() + begin_;
        const char* e = static_cast<const char*>(std::memchr(s, '\n', end_ - begin_));
        if (e != nullptr) {
          if (e > s) last = e[-1];
          skipped += static_cast<std::size_t>(e - s);
          begin_ += static_cast<std::size_t>(e - s) + 1;
          break;
        }
        if (end_ > begin_) last = buf_[end_ - 1];
        skipped += end_ - begin_;
        begin_ = end_;
      }
      if (last == '\r') --skipped;
      full_length = skipped;
      overlong = true;
      line = long_;
      return true;
    }
    if (!fill()) {
      if (end_ > begin_) {  // final line without terminator
        std::size_t len = end_ - begin_;
        const char* s = buf_.data() + begin_;
        begin_ = end_;
        full_length = len;
        if (len > 0 && s[len - 1] == '\r') --len, --full_length;
        if (len > max_line_) {
          overlong = true;
          len = max_line_;
        }
        line = std::string_view(s, len);
        return true;
      }
      return false;
    }
  }
}

}  // namespace gcpipe
