// add_velocity: copies a volume file's grids and adds a synthetic velocity grid for motion blur
// (docs/scene-format.md, "Motion blur"), for tests and the motion-blur benchmark on real density
// grids that come without a usable velocity.
//
//   add_velocity IN.vdb OUT.vdb [--density NAME] [--speed S] [--staggered] [--name vel]
//
// Design: the flow is a rising swirl about the density's vertical (index z) axis through the
// centre of its active box: v = S (-dy, dx, 0.5 r) / r_max in world units per second, with (dx, dy)
// the offset from the axis in units of the box's half width r_max and r = |(dx, dy)|: speed S at
// r = 1, up to about 1.6 S at the box's corners. It is set on the density's active voxels grown by 2 voxels (the
// background is 0), with the density grid's transform; --staggered marks the grid as a staggered
// (MAC) grid, with each component evaluated where such a grid stores it (half a voxel below the
// voxel centre along its axis). Deterministic: the same input gives the same file.
#include <openvdb/openvdb.h>
#include <openvdb/tools/Morphology.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

namespace {

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0 << " IN.vdb OUT.vdb [--density NAME] [--speed S] [--staggered] [--name vel]\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string in, out, density = "density", name = "vel";
  double speed = 1.0;
  bool staggered = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--density" && i + 1 < argc) density = argv[++i];
    else if (a == "--name" && i + 1 < argc) name = argv[++i];
    else if (a == "--speed" && i + 1 < argc) speed = std::atof(argv[++i]);
    else if (a == "--staggered") staggered = true;
    else if (in.empty() && !a.empty() && a[0] != '-') in = a;
    else if (out.empty() && !a.empty() && a[0] != '-') out = a;
    else return usage(argv[0]);
  }
  if (in.empty() || out.empty() || !std::isfinite(speed)) return usage(argv[0]);
  try {
    openvdb::initialize();
    openvdb::io::File f(in);
    f.open();
    openvdb::GridPtrVecPtr grids = f.getGrids();
    f.close();
    openvdb::FloatGrid::Ptr d;
    for (const auto& g : *grids)
      if (g->getName() == density && !d) d = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    if (!d) {
      std::cerr << in << ": no float grid named \"" << density << "\"\n";
      return 1;
    }
    const openvdb::CoordBBox box = d->evalActiveVoxelBoundingBox();
    const openvdb::Vec3d c = box.getCenter();
    const double r_max = std::max(1.0, 0.5 * std::max(box.dim().x(), box.dim().y()));
    openvdb::BoolGrid::Ptr mask = openvdb::BoolGrid::create(false);
    mask->tree().topologyUnion(d->tree());
    openvdb::tools::dilateActiveValues(mask->tree(), 2, openvdb::tools::NN_FACE_EDGE_VERTEX);
    // every voxel of the mask gets its velocity: an active tile (a whole 8^3 block, as dilation
    // leaves dense interiors) would give one voxel at its origin and leave the rest at 0
    mask->tree().voxelizeActiveTiles();
    auto vel = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    vel->setName(name);
    vel->setTransform(d->transform().copy());
    vel->setGridClass(staggered ? openvdb::GRID_STAGGERED : openvdb::GRID_UNKNOWN);
    auto acc = vel->getAccessor();
    const double h = staggered ? -0.5 : 0.0;  // where a staggered grid stores component a
    for (auto it = mask->cbeginValueOn(); it; ++it) {
      const openvdb::Coord q = it.getCoord();
      auto field = [&](double x, double y) {
        const double dx = (x - c.x()) / r_max, dy = (y - c.y()) / r_max;
        return openvdb::Vec3d(-dy, dx, 0.5 * std::sqrt(dx * dx + dy * dy)) * speed;
      };
      const openvdb::Vec3d vx = field(q.x() + h, q.y()), vy = field(q.x(), q.y() + h), vz = field(q.x(), q.y());
      acc.setValue(q, openvdb::Vec3s(float(vx.x()), float(vy.y()), float(vz.z())));
    }
    vel->pruneGrid();
    grids->push_back(vel);
    openvdb::io::File o(out);
    o.write(*grids);
    o.close();
  } catch (const std::exception& e) {
    std::cerr << "add_velocity: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
