// Reads text lines from a file descriptor with memory bounded by the longest allowed line, not by
// the file: a 1 GB program streams through a fixed buffer.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace gcpipe {

class LineReader {
 public:
  /// Reads from `fd` (not closed). Lines longer than `max_line` bytes are cut to that length and
  /// flagged, the rest of such a line is skipped without being stored.
  LineReader(int fd, std::size_t max_line);

  /// Next line without its terminator ("\n", "\r\n" or a final unterminated line). Returns false
  /// at end of input. `overlong` tells that the line was cut; `full_length` is its real length.
  bool next(std::string_view& line, bool& overlong, std::size_t& full_length);

  std::uint64_t bytes_read() const { return bytes_; }
  /// Non-empty after a read error (errno text).
  const std::string& error() const { return error_; }

 private:
  bool fill();
  int fd_;
  std::size_t max_line_;
  std::vector<char> buf_;
  std::size_t begin_ = 0, end_ = 0;
  bool eof_ = false;
  std::uint64_t bytes_ = 0;
  std::string error_;
  std::string long_;  // holds the head of a line that crossed the buffer end
};

}  // namespace gcpipe
