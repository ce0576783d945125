// Diagnostics: every rejected line is reported with file:line:col and a reason.
#pragma once

#include <cstdint>
#include <string>

namespace gcpipe {

enum class Severity : std::uint8_t { kNote = 0, kWarning = 1, kError = 2 };

/// One message about one place in one input file.
struct Diagnostic {
  std::string file;          //!< input file name as given by the user
  std::uint64_t line = 0;    //!< 1-based line, 0 when not about a line
  std::uint32_t column = 0;  //!< 1-based column, 0 when not about a column
  Severity severity = Severity::kError;
  std::string message;       //!< names the word and its value and says what to do
};

/// "file:line:col: error: message", the format compilers use, so editors can jump to it.
std::string format(const Diagnostic& d);

}  // namespace gcpipe
