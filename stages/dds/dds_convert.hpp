// Conversions between the stage cores' plain structs and the IDL wire types (idl/gcpipe.idl).
//
// Only node code includes this: it pulls in the generated header (light: std types only), never
// the Fast DDS entity headers. to_msg copies every field; from_msg checks every enumeration and
// returns false with a reason for a value the C++ enum does not have, so a corrupt or foreign
// sample is reported instead of becoming a wrong motion. Round trip: tests/dds_convert_test.cpp.
#pragma once

#include <cstddef>
#include <string>

#include "gcpipe.h"  // generated from idl/gcpipe.idl
#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "parse.hpp"

namespace gcpipe::dds {

void to_msg(const ResolvedBlock& block, msg::Block& out);
/// False (and `why` says which field and value) when an enumeration holds an unknown value.
bool from_msg(const msg::Block& in, ResolvedBlock& out, std::string* why = nullptr);

/// `status` is kRejected or kDeleted: the reason the line produced no block.
void to_msg(const Diagnostic& diag, LineStatus status, msg::LineDiagnostic& out);
bool from_msg(const msg::LineDiagnostic& in, Diagnostic& out, LineStatus& status,
              std::string* why = nullptr);

void to_msg(const ParseSummary& summary, msg::ParseCounts& out);
ParseSummary from_msg(const msg::ParseCounts& in);

/// The counts a finished program must satisfy, as one message per violated identity; empty
/// when consistent. `blocks` and `rejected`/`deleted` are what the consumer actually received.
std::string check_counts(const ParseSummary& summary, std::uint64_t blocks, std::uint64_t rejected,
                         std::uint64_t deleted);

}  // namespace gcpipe::dds
