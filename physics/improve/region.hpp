// Local mesh improvement (thesis sec. 5.2): after a conforming cut, only the elements around the
// cut are improved, as a mesh of their own whose outer nodes stay put, so its cost follows the
// region and not the object.
#pragma once

#include "improve/improve.hpp"

namespace cutsim {

// Improves the elements of `mesh` that have a node in `freeNodes` (indices into mesh), as their own
// mesh: every other node of theirs is fixed (as are opts.fixedNodes, indices into mesh), so the
// rest of the mesh is untouched and stays conforming. The improved elements replace the region's
// at the end of mesh.tets (flips change their number); node numbers do not change (edge collapses
// are off: they would orphan a node of the whole mesh). The report is the region's.
ImproveReport improveRegion(TetMesh& mesh, const std::vector<int>& freeNodes, ImproveOptions opts);

}  // namespace cutsim
