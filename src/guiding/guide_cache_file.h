// guide_cache_file.h: a trained guide cache in a file (`--guide-cache FILE`), so that the parts of
// a render (tiles, shards, devices, MPI ranks) read the one cache a single training fitted instead
// of each training its own over the full film (docs/guiding.md, "A cache file").
//
// Design: the file is the line "spectrack-guide-cache 1", one line of JSON (the key: everything
// the cache depends on, from the scene's hash to the training's samples, and the byte counts),
// then the device buffer's bytes (GuideCache::serialize: header, regions, nodes, pixel estimates).
// A reader compares the key field by field with its own render's and refuses a file of another
// render naming the field, and checks the bytes (counts, node links, finite and bounded values)
// before any of it reaches a kernel: a damaged or hostile file gives an Error naming the file, never
// a device fault or a silent wrong image. Writes go through OutputFile (a reader never sees half a
// file; parts that train at the same time write the same bytes).
#pragma once
#include <nlohmann/json.hpp>

#include <string>

#include "guiding/guide_cache.h"

namespace spectrack {

// Writes `cache` (its device buffer's bytes) with `key` to `path`; Error naming the path on failure.
void write_guide_cache_file(const std::string& path, const GuideCache& cache, const nlohmann::json& key);

// Reads the cache of `path` into `cache` (header, regions, nodes, pixel estimates); Error naming
// the path and the reason when it is not a guide cache, was written for another render (the key
// field that differs), or is damaged.
void read_guide_cache_file(const std::string& path, const nlohmann::json& key, GuideCache& cache);

}  // namespace spectrack
