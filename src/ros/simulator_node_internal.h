/// @file simulator_node_internal.h
/// What simulator_node*.cpp share: the waits of the node's services and lookups.
#pragma once

namespace deformable_flsm {

/// How long a service waits for the simulation thread to apply its command (s).
constexpr double kServiceTimeout = 2.0;
/// How often the first lookup in a foreign frame looks again while it waits, and ~step for the
/// state it reached to go out (s, wall time).
constexpr double kFirstTransformPoll = 0.01;

}  // namespace deformable_flsm
