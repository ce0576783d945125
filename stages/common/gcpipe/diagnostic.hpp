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

/// What a diagnostic stands for when it travels between stages (and on the DDS edges).
enum class DiagnosticKind : std::uint8_t {
  kLineRejected = 1,   //!< the parser rejected the line: no block
  kLineDeleted = 2,    //!< block delete '/': no block
  kBlockRejected = 3,  //!< a later stage rejected the line's block (a G275 cycle); the blocks
                       //!< replacing it (skip moves) carry the same line and come after it
};

/// "file:line:col: error: message", the format compilers use, so editors can jump to it.
std::string format(const Diagnostic& d);

}  // namespace gcpipe
