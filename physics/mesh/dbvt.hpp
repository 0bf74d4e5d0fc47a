// Helpers on Bullet's dynamic AABB tree (btDbvt) shared by the element broad phase and the
// contact's surface trees.
#pragma once

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <vector>

namespace cutsim {

// Every inner box of the tree merged again from its children, bottom up (each once): after the
// leaves' boxes were set in place, O(nodes), keeping the tree's shape (a deforming body's
// neighbours stay neighbours). stack: scratch.
inline void mergeInnerBoxes(btDbvt& tree, std::vector<btDbvtNode*>& stack) {
    if (!tree.m_root || tree.m_root->isleaf()) return;
    // pre-order onto the stack, then merged in reverse: children before their parent
    stack.assign(1, tree.m_root);
    for (size_t i = 0; i < stack.size(); ++i)
        for (btDbvtNode* c : stack[i]->childs)
            if (!c->isleaf()) stack.push_back(c);
    for (auto it = stack.rbegin(); it != stack.rend(); ++it)
        Merge((*it)->childs[0]->volume, (*it)->childs[1]->volume, (*it)->volume);
}

}  // namespace cutsim
