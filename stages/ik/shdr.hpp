// MTConnect SHDR traces (`timestamp|item|value[|...]`, one record per line) and the kinematic
// samples a machine trace gives: actual X Y Z A C with the controller's tool position `path_pos`.
//
// Per-line problems are counted, never thrown: UNAVAILABLE values mark an item unknown, garbled
// lines (too few fields, bad timestamp, a position that is not a number) are rejected and counted.
#pragma once

#include <cstdint>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

#include "gcpipe/block.hpp"

namespace gcpipe {

/// One SHDR record. `value` is the third field; condition items carry more fields after it.
struct ShdrRecord {
  double time = 0;          //!< seconds since 1970-01-01T00:00:00Z [s]
  std::string_view item;    //!< data item name, e.g. "Xposition"
  std::string_view value;   //!< third field, e.g. "12.5", "UNAVAILABLE", "-1.0 2.0 3.0"
};

/// ISO 8601 UTC time "YYYY-MM-DDThh:mm:ss[.ffffff]Z" in seconds since the epoch; NaN when the
/// text is not of that form.
double parse_iso8601_utc(std::string_view text);

/// Splits one line; false (record untouched) when it has fewer than three '|' fields or a bad
/// timestamp. The views point into `line`.
bool parse_shdr_line(std::string_view line, ShdrRecord& record);

/// One kinematic sample: the state after one adapter poll cycle.
struct KinematicSample {
  double time = 0;          //!< [s] since the epoch, of the cycle's first record
  Axes joints{};            //!< actual X Y Z [mm], A C [deg]
  Vec3 path_pos{};          //!< controller's tool position in work coordinates [mm]
  std::string program;      //!< program name in force ("" when unknown)
};

/// What reading a trace did with its lines.
struct ShdrStats {
  std::uint64_t lines = 0;
  std::uint64_t records = 0;      //!< well-formed lines
  std::uint64_t rejected = 0;     //!< garbled lines and unparsable values of used items
  std::uint64_t unavailable = 0;  //!< UNAVAILABLE values of used items
  std::uint64_t samples = 0;      //!< samples emitted (all six quantities known)
};

/// Reads a trace and returns one sample per poll cycle in which all of X Y Z A C and path_pos
/// are known. The adapter writes a cycle's records within a millisecond and sends values only
/// when they change, so records closer than `cycle_gap` [s] form one cycle and unchanged items
/// keep their last value.
std::vector<KinematicSample> read_kinematic_trace(std::istream& in, ShdrStats& stats,
                                                  double cycle_gap = 0.02);

}  // namespace gcpipe
