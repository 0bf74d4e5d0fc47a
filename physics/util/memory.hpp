// Memory a process may use, for refusing work up front instead of failing inside a parallel loop
// (a bad_alloc thrown in an OpenMP region cannot reach any handler).
#pragma once

#include <cstddef>
#include <string>

namespace cutsim {

// The smallest of physical memory, the address-space and data limits (setrlimit, ulimit -v) and
// the cgroup's memory.max [bytes].
double memoryLimitBytes();

// InputError naming `what` when `bytes` is above memoryLimitBytes(); says both in GB.
void checkMemory(const std::string& what, double bytes);

// Allocations of `threshold` bytes and more as their own mapped pages (glibc's M_MMAP_THRESHOLD;
// elsewhere nothing). A cut grows the per-element and per-node arrays by a few columns at each
// blade step: a mapped array grows by remapping its pages, where one on the heap is often copied
// whole into fresh pages, each a page fault (a 100k-element model's arrays are ~20 MB, its
// per-node vectors ~180 KB; docs/method.md, "What a blade step costs"). Not lower: llvmpipe's
// per-frame blocks of 64-128 KiB, mapped and unmapped each frame, made drawing several times
// slower. The cutsim program and the Python module set it at start; a program embedding the
// library should too. Freed heap tops are kept up to 64 MiB rather than handed back at once.
void mapLargeArrays(std::size_t threshold = 128 * 1024);

}  // namespace cutsim
