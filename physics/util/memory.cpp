#include "util/memory.hpp"

#include "util/input_error.hpp"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>

namespace cutsim {

double memoryLimitBytes() {
    double limit = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGESIZE));
    for (int r : {RLIMIT_AS, RLIMIT_DATA}) {
        rlimit rl{};
        if (getrlimit(r, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY)
            limit = std::min(limit, static_cast<double>(rl.rlim_cur));
    }
    std::ifstream cg("/sys/fs/cgroup/memory.max");
    double v = 0;
    if (cg >> v && v > 0) limit = std::min(limit, v);  // "max" fails to parse: no limit
    return limit;
}

void checkMemory(const std::string& what, double bytes) {
    const double limit = memoryLimitBytes();
    if (bytes <= limit) return;
    char buf[160];
    std::snprintf(buf, sizeof buf, "needs about %.3g GB of memory, above the %.3g GB this process may use", bytes / 1e9,
                  limit / 1e9);
    throw InputError(what + ": " + buf);
}

void mapLargeArrays(std::size_t threshold) {
#if defined(__GLIBC__)
    // a set threshold also stops glibc raising it to the largest block freed, which would put
    // the arrays back on the heap after the first one is freed
    mallopt(M_MMAP_THRESHOLD, static_cast<int>(threshold));
    // and stops it raising the trim threshold with it: left at 128 KiB, every thread's arena
    // hands its top back to the kernel after each frame's GL buffers are freed, and each of those
    // madvise calls stops the other core to flush its TLB. 64 MiB is glibc's own ceiling.
    mallopt(M_TRIM_THRESHOLD, 64 << 20);
#else
    (void)threshold;
#endif
}

}  // namespace cutsim
