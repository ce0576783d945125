// Stage `parse`: ISO 6983 text to resolved blocks.
//
// A streaming parser: one line in, at most one resolved block out, modal state carried between
// lines. Per-line problems are returned as a Diagnostic, never thrown; construction with a bad
// config throws ConfigError. Dialect: Fanuc first, LinuxCNC spellings where they do not conflict
// (see README.md, "The parse stage", for the accepted language and every error).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/machine.hpp"

namespace gcpipe {

class Config;

struct ParseOptions {
  Dialect dialect = Dialect::kFanuc;
  /// Fanuc's decimal-point rule: an axis value written without a point counts in the smallest
  /// input increment (0.001 mm, 0.0001 inch, 0.001 deg): `Z50` = 0.050 mm. Off: plain decimals.
  bool decimal_point_increments = false;
  bool block_delete = true;          //!< skip lines starting with '/' (the operator's switch)
  bool strict = false;               //!< stop at the first error instead of skipping the line
  std::size_t max_line_length = 256; //!< longer lines are rejected [bytes]
  Units initial_units = Units::kMillimetre;
  /// I J K as absolute centres from the start (G90.1), as some Heidenhain/Mastercam posts write
  /// them; default incremental (G91.1). The program's own G90.1/G91.1 still switch.
  bool absolute_arc_centres = false;
};

/// Reads the `parse` section of a pipeline config (every key documented in the README).
ParseOptions load_parse_options(const Config& parse_section);

/// What happened to each line; the counts add up: read = emitted + rejected + deleted.
struct ParseSummary {
  std::uint64_t lines_read = 0;
  std::uint64_t blocks_emitted = 0;
  std::uint64_t lines_rejected = 0;
  std::uint64_t lines_deleted = 0;  //!< skipped by block delete '/'
  std::uint64_t bytes_read = 0;
};

enum class LineStatus : std::uint8_t {
  kBlock,     //!< `block` holds the resolved line
  kRejected,  //!< `diag` says why; modal state unchanged
  kDeleted,   //!< block delete: the line is skipped on purpose
};

class Parser {
 public:
  /// `file` names the source in diagnostics.
  Parser(ParseOptions options, MachineConfig machine, std::string file);
  ~Parser();
  Parser(Parser&&) noexcept;
  Parser& operator=(Parser&&) noexcept;

  /// Parses the next line of the program (no terminator). `overlong_length` > 0 tells that the
  /// reader cut the line at max_line_length and it really had that many bytes.
  LineStatus parse_line(std::string_view line, ResolvedBlock& block, Diagnostic& diag,
                        std::size_t overlong_length = 0);

  const ParseSummary& summary() const;
  const ParseOptions& options() const;
  /// True after M2/M30: lines after the program end are still read and accounted for.
  bool ended() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe
