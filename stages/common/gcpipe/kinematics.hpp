// Kinematics of a table-table XYZAC machine (A tilts the table about X, C turns it about Z).
//
// Pinocchio's Model idea: `MachineKinematics` is an immutable description loaded once from the
// machine config; forward and inverse kinematics are free functions of (model, input): the same
// input gives the same output, bit for bit. Continuity across points comes in through the
// `previous` joint vector. One cache sits behind that: forward_kinematics keeps, per thread, the
// sin and cos of the last A and C angles (the simulation calls it twice a tick with the same
// angles, and sin/cos cost more than the rest); a cache hit returns the very values a call would.
//
// Frames (named aTb: the pose of frame b expressed in frame a):
//   k  carrier: fixed to the X/Y table carriage. Joint values are the ISO "tool relative to
//      workpiece" coordinates, so the gauge point of the spindle sits at (X, Y, Z) in k.
//   r  cradle:  turns with A about the A axis (parallel to X) through the pivot
//      a = c + (0, dy, dz).
//   w  workpiece: turns with C about the C axis (parallel to Z) through the C centre c; at
//      A = C = 0 it coincides with k, so at zero rotation work coordinates equal joint values
//      (tool length aside), as in LinuxCNC's trt kinematics.
//   t  tool: origin at the tool tip, z axis along the tool from tip into the spindle.
// The derivation, the sign conventions and the comparison with seed 000 and LinuxCNC are in
// stages/ik/README.md.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "gcpipe/block.hpp"

namespace gcpipe {

class Config;

/// Sense of the rotary joint values.
enum class RotaryConvention : std::uint8_t {
  /// A positive joint value turns the table right-handed about +X (A) or +Z (C). Tool axis in
  /// the workpiece: (sin A sin C, sin A cos C, cos A), as seed 000 eq. (4) and LinuxCNC's
  /// xyzac-trt with `conventional-directions 0` (its default).
  kTableRightHand = 0,
  /// ISO 841: a positive value turns the tool right-handed relative to the workpiece, i.e. the
  /// table turns the other way. Tool axis: (sin A sin C, -sin A cos C, cos A).
  kIso841 = 1
};

/// Travel range of one axis [mm or deg].
struct AxisRange {
  double min = 0;  //!< lower travel limit [mm, deg]
  double max = 0;  //!< upper travel limit [mm, deg]
  bool contains(double v) const { return v >= min && v <= max; }
};

/// Immutable kinematic model of a table-table XYZAC machine (see the frame list above).
struct MachineKinematics {
  Vec3 c_centre{};          //!< C axis centre c: the point of the C axis at table height with
                            //!< A = 0, in carrier coordinates (= machine coordinates at zero
                            //!< linear joints) [mm] (LinuxCNC x/y/z-rot-point)
  double a_offset_y = 0;    //!< dy: A pivot minus C centre along Y [mm] (LinuxCNC y-offset)
  double a_offset_z = 0;    //!< dz: A pivot minus C centre along Z [mm] (LinuxCNC z-offset)
  double tool_length = 0;   //!< tool length used when a caller gives none [mm]
  RotaryConvention convention = RotaryConvention::kTableRightHand;
  std::array<AxisRange, kNumAxes> travel{{{-1e4, 1e4}, {-1e4, 1e4}, {-1e4, 1e4},
                                          {-180, 180}, {-1e6, 1e6}}};  //!< [mm, deg]
  Axes max_velocity{};      //!< per axis [mm/s, deg/s]
  Axes max_acceleration{};  //!< per axis [mm/s^2, deg/s^2]
  /// Tilt of the tool vector from the C axis below which C is undefined for IK and the previous
  /// C is kept [deg]. Keeping C moves the tool axis by at most 2x this angle.
  double c_hold_tilt = 1e-7;
  /// |A| below which a tool-vector IK result is flagged near-singular: C moves by
  /// (tilt change)/sin A there, so small tool-vector noise turns into large C motion [deg].
  double near_singular_tilt = 1.0;
};

/// Tool tip [mm] and unit tool axis (pointing from the tip into the spindle), both in the
/// workpiece frame w.
struct ToolPose {
  Vec3 tip{};
  Vec3 axis{0, 0, 1};
};

/// KDL-style status band of one IK result.
enum class IkStatus : std::uint8_t {
  kOk = 0,        //!< exact solution, within travel
  kDegraded = 1,  //!< a solution, but see flags (near singularity, C held, branch switch, ...)
  kFailed = 2     //!< no usable solution: unreachable input or out of travel (joints still hold
                  //!< the best candidate so the caller can report by how much)
};

/// Bits of IkResult::flags. Bits 0..7: analytic IK; bits 8..15: neural IK (set by the IK stage).
enum IkFlag : std::uint32_t {
  kIkNearSingular = 1u << 0,         //!< tool-vector mode, |A| < near_singular_tilt (degraded)
  kIkCKeptAtSingularity = 1u << 1,   //!< tilt < c_hold_tilt: C undefined, previous C kept
                                     //!< (degraded)
  kIkBranchSwitch = 1u << 2,         //!< sign of A differs from the previous point's (degraded)
  kIkBranchByLimit = 1u << 3,        //!< the branch nearest the previous point was out of travel,
                                     //!< the other one was taken (degraded)
  kIkTravelLimit = 1u << 4,          //!< no candidate within travel; joints = nearest candidate
                                     //!< (failed)
  kIkUnreachable = 1u << 5,          //!< input not finite or tool vector of zero length (failed)
  kIkNeuralDiverged = 1u << 8,       //!< neural joints differ from analytic beyond tolerance
  kIkNeuralOutsideEnvelope = 1u << 9,//!< input outside the neural model's training envelope
  kIkNeuralFailed = 1u << 10,        //!< neural model gave no finite answer
};

/// One IK answer. `joints` are X Y Z [mm], A C [deg]; C is unwrapped (may exceed +-360).
struct IkResult {
  Axes joints{};
  IkStatus status = IkStatus::kOk;
  std::uint32_t flags = 0;  //!< IkFlag bits
};

/// Tool pose in the workpiece frame for joints X Y Z [mm] A C [deg], with m.tool_length.
ToolPose forward_kinematics(const MachineKinematics& m, const Axes& joints);
/// Same with an explicit tool length [mm] (G43 H in force).
ToolPose forward_kinematics(const MachineKinematics& m, const Axes& joints, double tool_length);

/// Tool-vector IK: both branches A = +-acos(Ok); the branch is chosen first by travel limits,
/// then by continuity with `previous` (squared A and C distance), except when leaving the pole
/// (|previous A| <= c_hold_tilt), where the side of A with the wider travel is taken; C is
/// unwrapped to the turn nearest previous[C] that lies within travel. Uses m.tool_length.
IkResult inverse_kinematics(const MachineKinematics& m, const ToolPose& pose, const Axes& previous);
/// Same with an explicit tool length [mm].
IkResult inverse_kinematics(const MachineKinematics& m, const ToolPose& pose, const Axes& previous,
                            double tool_length);

/// Tool-centre-point IK with A and C given [deg] (G43.4 / M428 with rotary words): only the
/// linear joints are solved. Flags only travel limits and non-finite input.
IkResult inverse_kinematics_ac(const MachineKinematics& m, const Vec3& tip, double a_deg,
                               double c_deg);
/// Same with an explicit tool length [mm].
IkResult inverse_kinematics_ac(const MachineKinematics& m, const Vec3& tip, double a_deg,
                               double c_deg, double tool_length);

/// Batched tool-vector IK over a path: point i uses the result of point i-1 as `previous`
/// (point 0 uses `previous`). `out.size()` must equal `poses.size()`.
void inverse_kinematics_path(const MachineKinematics& m, std::span<const ToolPose> poses,
                             const Axes& previous, double tool_length, std::span<IkResult> out);

/// Tool axis in the workpiece frame for rotary joints [deg] (unit vector).
Vec3 tool_axis(const MachineKinematics& m, double a_deg, double c_deg);

/// Travel check of all five joints; returns a bit per axis (bit i: axis i outside travel).
std::uint8_t joints_outside_travel(const MachineKinematics& m, const Axes& joints);

/// Readable list of the set flags, e.g. "near_singular|branch_switch"; "" for none.
std::string ik_flags_to_string(std::uint32_t flags);
const char* to_string(IkStatus s);

/// Reads the `kinematics` and `limits` sections of a machine file's root mapping (unknown keys
/// rejected); throws ConfigError naming key, value and reason.
MachineKinematics load_kinematics(const Config& machine_root);

}  // namespace gcpipe
