// Resolved G-code blocks: what every stage after `parse` consumes.
//
// A resolved block is one source line after modal resolution: absolute targets in mm and degrees
// (units, incremental mode, work offsets applied), the full modal state in force, and where it came
// from. Downstream stages never look at G-code text again.
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace gcpipe {

/// Machine axes in the order used everywhere: X Y Z [mm], A C [deg].
enum Axis : int { kX = 0, kY = 1, kZ = 2, kA = 3, kC = 4 };
inline constexpr int kNumAxes = 5;
inline constexpr char kAxisLetters[kNumAxes] = {'X', 'Y', 'Z', 'A', 'C'};
using Axes = std::array<double, kNumAxes>;  //!< X Y Z [mm], A C [deg]
using Vec3 = std::array<double, 3>;         //!< a point or vector in X Y Z [mm]

/// Motion of one block (modal group 1 plus dwell and the slot cycle).
enum class Motion : std::uint8_t {
  kNone = 0,        //!< the block moves nothing (state change, comment, M code only)
  kRapid = 1,       //!< G0
  kLinear = 2,      //!< G1
  kArcCW = 3,       //!< G2
  kArcCCW = 4,      //!< G3
  kDwell = 5,       //!< G4
  kTrochoidSlot = 6 //!< G275 trochoidal slot cycle, expanded by the trochoid stage
};

enum class Plane : std::uint8_t { kXY = 17, kZX = 18, kYZ = 19 };  //!< G17 / G18 / G19
enum class FeedMode : std::uint8_t { kUnitsPerMinute = 94, kInverseTime = 93 };  //!< G94 / G93
enum class Spindle : std::uint8_t { kOff = 5, kCW = 3, kCCW = 4 };  //!< M5 / M3 / M4
/// G64 (blend corners, within G64 P if given) / G61 (exact stop at every block end) / G61.1
/// (exact path: modelled as G61, since this control model follows a path exactly only by stopping).
enum class PathMode : std::uint8_t { kBlend = 0, kExactStop = 1, kExactPath = 2 };
enum class Units : std::uint8_t { kMillimetre = 21, kInch = 20 };  //!< G21 / G20 (source only)

/// Program-flow M codes (modal group 4) and the tool change; at most one per block.
enum class ProgramStop : std::uint8_t {
  kNone = 0,
  kStop = 1,          //!< M0
  kOptionalStop = 2,  //!< M1
  kEnd = 3,           //!< M2
  kEndRewind = 4      //!< M30
};

/// G-code dialect where controls disagree.
enum class Dialect : std::uint8_t {
  kFanuc,     //!< G4 P milliseconds / X seconds; G43, G43.4, G49 one group (G43 ends TCP)
  kLinuxCnc,  //!< G4 P seconds; TCP is kinematics (M428 on, M429/M430 off), G43/G49 length only
};

/// Coolant bits: M7 mist and M8 flood may both be on; M9 clears both.
enum Coolant : std::uint8_t { kCoolantOff = 0, kCoolantMist = 1, kCoolantFlood = 2 };

/// Parameters of the G275 trochoidal slot cycle, resolved to absolute mm (see stages/trochoid).
struct TrochoidSlot {
  Vec3 start{};          //!< slot centre-line start = position before the block [mm]
  Vec3 end{};            //!< slot centre-line end (X Y from the block, Z = start Z) [mm]
  double bottom = 0;     //!< Z of the slot floor [mm]
  double clearance = 0;  //!< R: Z of the retract plane [mm]
  double width = 0;      //!< W: slot width [mm]
  double step = 0;       //!< K: advance per trochoid revolution [mm]
  double depth_step = 0; //!< Q: axial step-down per pass [mm]; 0 = full depth in one pass
  double tool_diameter = 0; //!< D or the active tool's diameter from the machine config [mm]
  bool climb = true;     //!< P+1 climb (default), P-1 conventional
};

/// A non-modal code of the source that sets or uses a frame the control holds: its work offsets,
/// the G92 shift, tool entries, reference positions, machine coordinates. The parser resolves it
/// (targets are machine coordinates of the machine file); the write stage writes it as the source
/// said it, so that output.nc runs in the control's own frames (docs/reference.md, "The write stage").
enum class FrameCode : std::uint8_t {
  kNone = 0,
  kSetOrigin = 1,       //!< G10 L2 P: the origin of a work system is the words
  kSetOriginHere = 2,   //!< G10 L20 P (LinuxCNC): the origin such that the position reads as the words
  kShift = 3,           //!< G92: the position reads as the words
  kShiftClear = 4,      //!< G92.1
  kShiftSuspend = 5,    //!< G92.2
  kShiftRestore = 6,    //!< G92.3
  kLocalShift = 7,      //!< G52: the origin shifted by the words
  kHome = 8,            //!< G28: through the words to the first reference position
  kHome2 = 9,           //!< G30: the same to the second
  kMachine = 10,        //!< G53: the words are machine coordinates
  kToolTable = 11,      //!< LinuxCNC G10 L1 P: Z length, R radius of tool P
  kToolTableHere = 12,  //!< LinuxCNC G10 L10 P: the length such that the position reads as Z
  kToolLength = 13,     //!< Fanuc G10 L10 P R: length geometry (G91: R is added)
  kToolRadius = 14,     //!< Fanuc G10 L12 P R: radius geometry (G91: R is added)
};

/// How the source stated its frames on a block's line: what a writer needs to say it again in the
/// control's frames instead of the machine file's. Blocks the parser expands (a G28, a cycle)
/// carry their line's.
struct SourceFrame {
  /// Origin the program's values are measured from: its G5x origin as the program has set it
  /// (G10) plus the G92/G52 shift in force [mm, deg], in the machine file's machine coordinates.
  /// target - origin = the position in the program's own coordinates.
  Axes origin{};
  FrameCode code = FrameCode::kNone;  //!< the frame statement on the line, if any
  std::uint8_t words = 0;             //!< axis bits the statement gave (in `values`)
  bool incremental = false;           //!< G91 in force on the line
  bool intermediate = false;          //!< G28/G30: this block is the move to the intermediate point
  bool selects_work_offset = false;   //!< the line has G54..G59
  bool sets_tool_length = false;      //!< the line has G43, G43.4, G43.5 or G49
  bool has_r = false;                 //!< a G10 tool entry's R word is in `r`
  std::int32_t p = 0;                 //!< G10 P: work system (0 = the one in force) or tool
  Axes values{};  //!< the statement's axis words [mm, deg], as written (G91: increments)
  double r = 0;   //!< G10 tool entry: the R word [mm]
  /// G10 L2/L20: the system's origin after the statement (machine file frame); tool entries:
  /// [kZ] the entry's length and [kX] its radius after it [mm]. For a dialect that cannot say
  /// the statement as written.
  Axes resolved{};
};

/// One source line after modal resolution. Plain data; copying is cheap apart from the strings.
struct ResolvedBlock {
  // -- where it came from
  std::uint64_t line = 0;  //!< 1-based line number in the source file
  std::string text;        //!< the source line as read (without the line terminator)
  std::string comment;     //!< text of the comments on the line, joined by " | ", no delimiters

  // -- what it does
  Motion motion = Motion::kNone;
  Axes start{};            //!< position before the block [mm, deg], machine coordinates
  Axes target{};           //!< position after the block [mm, deg]: program value in mm/deg,
                           //!< incremental moves summed, plus work_origin (machine coordinates)
  std::uint8_t axis_words = 0;  //!< bit i set: axis i was programmed in this block

  // -- arcs (kArcCW / kArcCCW only)
  Plane plane = Plane::kXY;
  Vec3 centre{};           //!< arc centre [mm], machine coordinates; its coordinate along the
                           //!< plane normal is the start's
  double radius = 0;       //!< radius at the start point [mm]
  std::int32_t turns = 1;  //!< full turns + 1 for the partial one (LinuxCNC P word); 1 = plain arc

  // -- modal state in force for this block
  double feed = 0;                          //!< mm/min (G94) or 1/min (G93)
  FeedMode feed_mode = FeedMode::kUnitsPerMinute;
  double dwell = 0;                         //!< G4 dwell time [s]
  double spindle_speed = 0;                 //!< S [rev/min]
  double path_tolerance = 0;                //!< G64 P in force [mm] (0: none programmed; the
                                            //!< planner then takes compensate.path_tolerance)
  PathMode path_mode = PathMode::kBlend;    //!< G64 / G61 / G61.1 in force
  Spindle spindle = Spindle::kOff;
  std::int32_t tool = 0;                    //!< T selected (loaded by M6)
  std::int32_t tool_in_spindle = 0;         //!< tool loaded by the last M6
  std::int32_t tool_length_offset = 0;      //!< H register in force (0 = none)
  double tool_length = 0;                   //!< length from the H register [mm] when active
  bool tool_length_active = false;          //!< G43 / G43.4 in force
  bool tcp = false;                         //!< tool-centre-point mode (G43.4, G43.5, M428) in force
  Vec3 tool_vector{0, 0, 1};   //!< unit tool axis tip->spindle in the workpiece frame (G43.5 I J K); valid when tool_vector_mode
  bool tool_vector_mode = false; //!< G43.5 in force: orientation programmed as I J K, the IK chooses A and C
  std::uint8_t coolant = kCoolantOff;       //!< Coolant bits
  std::int32_t work_offset = 54;            //!< G54..G59
  Axes work_origin{};                       //!< origin of that system [mm, deg] (machine config)
  Units source_units = Units::kMillimetre;  //!< units the source used (targets are always mm)
  bool tool_change = false;                 //!< M6 in this block
  ProgramStop stop = ProgramStop::kNone;    //!< M0/M1/M2/M30 in this block
  std::int32_t program_number = -1;         //!< O / ':' number on this line, -1 if none
  bool percent = false;                     //!< the line is a '%' tape marker
  SourceFrame frame{};                      //!< how the source stated its frames (write stage)

  // -- cycle (kTrochoidSlot only)
  TrochoidSlot slot{};
};

/// True when two blocks mean the same thing to a machine: every resolved field equal (numbers
/// within `tol`, relative to max(1, |value|)); line, text and N numbers are not compared.
bool same_meaning(const ResolvedBlock& a, const ResolvedBlock& b, double tol = 1e-9,
                  std::string* why = nullptr);

const char* to_string(Motion m);

/// What the passes over a whole program read of each block: its line, motion, stops, TCP mode and
/// the tool length in force. 32 bytes where a block is 616: a pass that reads a field or two of every
/// block (segments, the planner's rests, the tool tip of each raw sample) maps a fifteenth of
/// the pages, and those passes run at gigabytes a second, faster than any trimming of the
/// resident set can follow (issue 12: the program's blocks were what still grew with it).
struct BlockBrief {
  std::uint64_t line = 0;
  double tool_length = 0;     //!< ResolvedBlock::tool_length (when tool_length_active)
  double path_tolerance = 0;  //!< G64 P in force [mm] (0: none)
  Motion motion = Motion::kNone;
  ProgramStop stop = ProgramStop::kNone;
  PathMode path_mode = PathMode::kBlend;
  bool tool_length_active = false;
  bool tcp = false;
};

inline BlockBrief brief_of(const ResolvedBlock& b) {
  return {b.line, b.tool_length, b.path_tolerance, b.motion, b.stop, b.path_mode, b.tool_length_active, b.tcp};
}

}  // namespace gcpipe

namespace gcpipe {

/// Appends one block as a single-line JSON object (fields as in ResolvedBlock; numbers shortest
/// round trip). Used by `gcpipe parse --json` and the monitors.
void append_json(std::string& out, const ResolvedBlock& b);

}  // namespace gcpipe
