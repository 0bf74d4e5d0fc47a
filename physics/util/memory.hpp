// Memory a process may use, for refusing work up front instead of failing inside a parallel loop
// (a bad_alloc thrown in an OpenMP region cannot reach any handler).
#pragma once

#include <string>

namespace cutsim {

// The smallest of physical memory, the address-space and data limits (setrlimit, ulimit -v) and
// the cgroup's memory.max [bytes].
double memoryLimitBytes();

// InputError naming `what` when `bytes` is above memoryLimitBytes(); says both in GB.
void checkMemory(const std::string& what, double bytes);

}  // namespace cutsim
