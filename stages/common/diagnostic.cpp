#include "gcpipe/diagnostic.hpp"

namespace gcpipe {

std::string format(const Diagnostic& d) {
  std::string s = d.file.empty() ? std::string("<input>") : d.file;
  if (d.line > 0) {
    s += ':' + std::to_string(d.line);
    if (d.column > 0) s += ':' + std::to_string(d.column);
  }
  switch (d.severity) {
    case Severity::kNote: s += ": note: "; break;
    case Severity::kWarning: s += ": warning: "; break;
    case Severity::kError: s += ": error: "; break;
  }
  s += d.message;
  return s;
}

}  // namespace gcpipe
