// media_bounds.h: the world boxes of a scene's media, for framing (scene/framing.h) and
// `spectrack info`. A VDB medium's box is where its density can be non-zero: the active index
// box widened by one voxel on each side (the trilinear support, volume.h), through the grid's
// own transform and then the medium's "transform" (scale, rotate x, y, z, translate); a
// homogeneous medium's box is its "bounds".
#pragma once
#include <vector>

#include "scene/framing.h"
#include "scene/scene.h"
#include "volume/volume.h"

namespace spectrack {

// The world point of a grid index point (the grid transform, then the medium's transform).
Vec3 medium_index_to_world(const MediumDesc& md, const GridData& g, const Vec3& index);

// The box of a loaded VDB medium (an empty grid gives a degenerate box at its origin).
Box3 medium_world_box(const MediumDesc& md, const GridData& g);

// Every medium's box, loading each grid (throws Error naming the file and field).
std::vector<Box3> media_world_boxes(const SceneDesc& scene);

}  // namespace spectrack
