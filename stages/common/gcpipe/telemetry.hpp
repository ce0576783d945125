// What stages show monitors while a program runs, beside the program itself: the IK stage's
// result for every block end point, the simulate stage's every tick. Emitted through
// pipeline::Emitter only when somebody listens (a DDS node publishes them on keep-last monitor
// topics, idl/gcpipe.idl IkBatch and SampleBatch); batch mode has no listener and pays nothing.
#pragma once

#include <cstdint>

#include "gcpipe/block.hpp"

namespace gcpipe {

/// One IK result: a block's end point solved by the analytic IK and, when a model is configured,
/// the neural IK beside it.
struct IkTelemetry {
  std::uint64_t line = 0;     //!< source line of the block
  Axes joints{};              //!< analytic joints [mm, deg]
  Axes neural_joints{};       //!< [mm, deg], valid when has_neural
  bool has_neural = false;
  std::uint8_t status = 0;    //!< gcpipe::IkStatus
  std::uint32_t flags = 0;    //!< gcpipe::IkFlag bits
};

/// One simulated tick of the machine (interpolator, acc/dec, drives, forward kinematics).
struct SampleTelemetry {
  std::uint64_t tick = 0;     //!< 0, 1, 2, ... from the program's start
  double time = 0;            //!< [s] since the program's start
  std::uint64_t line = 0;     //!< source line of the block being interpolated
  Axes command{};             //!< smoothed command [mm, deg]
  Axes actual{};              //!< actual joints [mm, deg]
  Vec3 tip{};                 //!< actual tool tip, workpiece frame [mm]
  double contour = 0;         //!< contour error [mm]; 0 off cutting moves (rapids)
  std::uint8_t saturated = 0; //!< bit per axis: torque-limited in this tick
};

}  // namespace gcpipe
