// Measured traces for the calibration: commanded and actual axis positions at the control's
// sampling period, read from the shared trace CSV (stages/servo/trace.hpp, plus optional per-axis
// torque or current columns and optional [unit] suffixes), the University of Michigan CSV
// (100 ms, velocities and currents), LinuxCNC halsampler output (no header: the user gives the
// column map) or an MTConnect SHDR stream (records on change, grouped into rows per adapter
// cycle). Every rejected row is a Diagnostic file:line:col with the reason; with skip_bad_rows
// the usable rest is kept and the dropped rows are counted.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <istream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"

namespace gcpipe::calibrate {

enum class TraceFormat : std::uint8_t { kSharedCsv, kUmichCsv, kHalsampler, kShdr };

/// "csv" / "shared", "umich", "halsampler", "shdr"; nullopt for anything else.
std::optional<TraceFormat> parse_format(std::string_view name);
std::string_view format_name(TraceFormat f);

/// One trace on a uniform time grid. Positions mm / deg, time s.
struct MeasuredTrace {
  std::string file;
  TraceFormat format = TraceFormat::kSharedCsv;
  double period = 0;                                  //!< median sample spacing [s]
  std::vector<double> t;                              //!< [s]
  std::array<std::vector<double>, kNumAxes> command;  //!< [mm, deg]
  std::array<std::vector<double>, kNumAxes> actual;   //!< [mm, deg]
  /// Per axis torque [N*m] or current [A] when the file has it (empty otherwise).
  std::array<std::vector<double>, kNumAxes> effort;
  std::array<std::string, kNumAxes> effort_kind;      //!< "torque", "current" or ""
  /// UMich only: actual and commanded velocities [mm/s] (positions there are quantised to 1 mm).
  std::array<std::vector<double>, kNumAxes> actual_velocity, command_velocity;
  std::uint64_t lines_read = 0;    //!< data lines in the file
  std::uint64_t rows_skipped = 0;  //!< rejected rows dropped (skip_bad_rows)
  std::uint64_t rows_unused = 0;   //!< good rows outside the longest gap-free stretch
  std::size_t size() const { return t.size(); }
};

struct ReadOptions {
  std::optional<TraceFormat> format;  //!< nullopt: detected from the header
  bool skip_bad_rows = false;         //!< keep the usable rest instead of rejecting the file
  std::size_t min_rows = 200;         //!< fewer usable rows: rejected (a fit needs transients)
  double max_gap = 1.5;               //!< a spacing above max_gap x period is a gap
  /// halsampler: one name per column, in the order of the sampler's cfg string (with `n` first
  /// when halsampler ran with -t): n, t, X_cmd..C_cmd, X..C, <axis>_torque, <axis>_current, or
  /// `-` to ignore a pin. SHDR: QUANTITY=ITEM pairs overriding the default item names
  /// (X=Xposition .. C=Cposition, X_cmd=Xcommanded .. C_cmd=Ccommanded).
  std::vector<std::string> columns;
  double period = 0;                  //!< halsampler without a `t` column: the thread period [s]
  /// SHDR records within this time [s] of a cycle's first record form one row: an adapter writes
  /// one poll cycle's changes within a millisecond (NIST GF Agie: 0.2 ms), polls far apart.
  double shdr_cycle = 0.002;
};

struct ReadResult {
  std::optional<MeasuredTrace> trace;   //!< set when the file (or its usable rest) is accepted
  std::vector<Diagnostic> diagnostics;  //!< every rejected row, and why a file was rejected
};

/// Reads one trace. Never throws for bad content: problems are diagnostics.
ReadResult read_trace(std::istream& in, const std::string& file, const ReadOptions& options);
/// Same from a path; an unreadable file is one diagnostic.
ReadResult read_trace_file(const std::filesystem::path& path, const ReadOptions& options);

}  // namespace gcpipe::calibrate
