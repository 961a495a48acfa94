// guide_cache.h: the host side of the guide cache (kernels/guiding.h): its regions over the media,
// and the fit of every region's mixture from the radiance records of a training pass.
//
// Design: the regions start as the cells of one uniform grid over the union of the media's world
// boxes (the longest axis cut into kGuideGridCells cells, the others into as many cells of about
// the same edge); every cell is the root of a kd-tree whose leaves are the regions, refined after
// each training pass where the pass's records crowd (refine_guide_regions, guide_tree.cpp), so the
// regions follow where the paths scatter: a dense medium's lit shell and its dark core end up in
// different regions. The memory is bounded by kGuideMaxRegions. The fit bins the records by
// position into the current regions and sorts them by (region, key),
// so its input does not depend on the order in which the device appended them, and fits each
// region with enough records by fit_vmf_mixture (a pure function of its input): the cache after a
// training pass depends only on the records' contents, which depend only on the scene, the
// settings and the seed.
#pragma once
#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <functional>
#include <limits>
#include <vector>

#include "kernels/types.h"
#include "kernels/guiding.h"

namespace spectrack {

// Cells along the longest axis of the media's box.
constexpr int kGuideGridCells = 8;
// A region fits its own records from this many on (their effective count for the fit, Kish's
// (sum w)^2 / sum w^2); below, it takes a pooled fit, or phase sampling alone.
constexpr int kGuideMinRecords = 32;
// Records of one region that the fit reads at most (every k-th in key order beyond).
constexpr int kGuideMaxRecordsPerRegion = 2048;
// The selection probability of the guide in a region that has a fit, where it is not learned
// (with the phase product; SPECTRACK_GUIDE_ALPHA sets another); learned, it is the candidate of
// 0.1, ..., kGuideAlphaMax that removes most variance by the region's held-out records, and 0
// unless that removal is kGuideAlphaZ standard errors above 0 and kGuideAlphaGain of the unguided
// variance (guide_cache.cpp learn_alpha).
constexpr float kGuideAlpha = 0.5f;
constexpr float kGuideAlphaMax = 0.9f;
constexpr double kGuideAlphaZ = 2.0;
constexpr double kGuideAlphaGain = 0.1;
// Training passes: their samples per pixel over the full film, in order. One pass of 4: every pass
// is a stage loop that ends with its own tail of the longest paths (in dense media most of its
// iterations), and caches fitted from 1 or 2 samples per pixel guided the next passes worse than
// the phase function alone (docs/guiding.md, "Where a guided render's time goes").
constexpr int kGuideTrainingSpp[] = {4};
constexpr int kGuideTrainingPasses = int(sizeof(kGuideTrainingSpp) / sizeof(kGuideTrainingSpp[0]));
// The training passes' random streams: the render's seed xor this.
constexpr uint32_t kGuideTrainingSeed = 0x6a09e667u;
// What a training pass's records hold, in a cache file's key (guide_cache_file.h), so that a file
// trained by a build whose records differ is refused: 2 = radiance in the film's unit (spectral
// lanes weighed by the film, kernels/guide_paths.h guide_lane_weights), no records at ground
// vertices or shadow-catcher hits; 3 = records from at most kGuideRecordSamples camera samples of
// a pass.
constexpr int kGuideRecordsVersion = 3;
// The camera samples of a training pass that make records, at most: a pass renders every pixel of
// the film, and on a large film only a hashed fraction of its samples (the same set in every part
// of a render: kernels/guiding.h guide_sample_records) records, so that the records' memory and the
// host's fit stay bounded whatever the film (where every sample of a pass of 4 samples on 512x384
// pixels records, it makes 7.3 M records, 350 MB, and 4.4-4.7 s of fit on 2 cores; docs/guiding.md,
// "Records"). 2^18 is above the bench films' passes (128x96 x 4 = 49152; twice the film 196608), so
// every sample of theirs records. The other samples render the same paths and stay in the image.
constexpr int64_t kGuideRecordSamples = int64_t(1) << 18;
// The fraction of a training pass's camera samples (`pixels` of the full film times `spp`) that make
// records: 1 up to `budget` samples (0: every sample), else budget / samples.
float guide_record_fraction(int64_t pixels, int spp, int64_t budget);
// The bound of a render: SPECTRACK_GUIDE_RECORD_SAMPLES=N for measurements, else kGuideRecordSamples.
int64_t guide_record_samples_setting();
// Region refinement: a region that holds more than this many radiance records of a training pass
// splits (its halves hold at least half as many each: the split is at their median), and the cache
// holds at most kGuideMaxRegions regions (176 bytes each, and two kd-tree nodes of 8 bytes).
constexpr size_t kGuideSplitRecords = 512;
constexpr size_t kGuideMaxRegions = size_t(1) << 16;

// Guided roulette and splitting in the render (kernels/guiding.h guide_rrs): the most paths one
// path splits into, the ratio of expected contribution to the pixel's estimate below which roulette
// applies, and the least survival probability.
constexpr int kGuideSplitMax = 8;
constexpr float kGuideRouletteBelow = 0.25f;
constexpr float kGuideSurvivalFloor = 0.25f;
// The least pixel estimate, as a fraction of the film's mean: a dark pixel's estimate is noisy, and
// its paths' expected contributions must not look huge against it (they would all split).
constexpr double kGuidePixelFloor = 0.05;

// Scatter events that are guided: those of depth below this (every event). Each region's selection
// probability is learned from held-out records (alpha = 0 where the guide does not pay back its
// weights' spread), so guiding every event measures no worse than guiding the first alone on the
// bench scenes (variance within 1% of the unguided render at 64 spp) and removes more where the
// light is concentrated (the oracle scene: 2.1x less variance, against 1.4x for the first event;
// docs/guiding.md, "Every event with the learned alpha"). With alpha 0.5 everywhere deeper events
// lost by up to three orders of magnitude: the weights f_phase / p_mix of every guided event multiply.
constexpr int kGuideDepth = std::numeric_limits<int>::max();
// The guided depth of a render: RenderOptions::guide_depth where set (tests), else the environment's
// SPECTRACK_GUIDE_DEPTH (measurements; 0 or a negative value: every scatter event), else kGuideDepth.
int guide_depth_setting(int option);

// Whether the mixtures hold the incident radiance and guided events sample its product with the
// phase function (st_guide_header.phase_product, kernels/guiding.h): SPECTRACK_GUIDE_PRODUCT=0|1,
// else off. A fit of f_phase L averaged over the region's propagation directions ignores the phase
// function at events deeper than the first (a second moment of 1.15 per event on dense_subsurface,
// 1.48 on the clouds, against 1.07 and 1.17 with the product: docs/guiding.md, "A well-trained
// cache"), but the product's pdf depends on each event's direction, so its selection probability
// cannot be learned from the records (it is fixed at 0.5), and at alpha 0.5 on every event it loses
// on the bench scenes where the learned alpha leaves the mixture's regions unguided.
bool guide_phase_product_setting(int guided_depth);

// Whether the fit weighs guided vertices by the whole rest of their paths (GuideCache::full_path, as
// Open PGL's samples do) and not by the ring's last bounces: SPECTRACK_GUIDE_FULL_PATH=0|1, else off.
// Measurements only: the join (end - total) / beta sums the path's shadow-ray folds in an order that
// depends on the shadow ring's lag, so its weights, and the fit, change in the last bits with the
// path slots (GuidingRender.EveryScatterEventGuidedDoesNotDependOnPathSlots fails with it).
bool guide_full_path_setting(bool phase_product);

// The training schedule of a render, for measurements of how much training the guide needs
// (docs/guiding.md, "A well-trained cache"): SPECTRACK_GUIDE_TRAINING=s1,s2,... gives the passes'
// samples per pixel (each pass guided by the cache the previous one fitted, each fit from its own
// pass's records), and SPECTRACK_GUIDE_TRAINING_KEEP=0 drops the passes' samples from the image (the
// render then renders all its samples after them, so guided and unguided renders compare at equal
// spp with any training). Without them, kGuideTrainingSpp and the samples are kept.
struct GuideTraining {
  std::vector<int> spp;  // per pass
  bool keep = true;      // the passes' samples are part of the image (they then leave one to the render)
  // The samples of the sequence that are the passes' when kept (the first ones: docs/guiding.md,
  // "Determinism across shards"); 0 when they are dropped.
  int samples() const {
    int n = 0;
    for (int k : spp) n += k;
    return keep ? n : 0;
  }
};
GuideTraining guide_training_setting();

// Bytes of the record buffer for Q path slots: the count, and in training passes the records of
// one iteration (a slot records the fit's and the radiance record of the vertex that leaves its
// ring at a scatter event; when it finishes, those of its ring and its end record), the slots'
// guide state and the vertex rings (kernels/guiding.h); with splitting in the render, the count
// and the slots' state.
inline uint64_t guide_record_capacity(uint64_t Q, int guided_depth = kGuideDepth) {
  return Q * uint64_t(ST_GUIDE_RING + std::min(guided_depth, ST_GUIDE_RING) + 1);
}
inline size_t guide_record_buffer_bytes(uint64_t Q, bool training, bool splitting = false, int guided_depth = kGuideDepth) {
  return 16 + (training ? guide_record_capacity(Q, guided_depth) * sizeof(st_guide_record) +
                              Q * (sizeof(st_guide_slot) + ST_GUIDE_RING * sizeof(st_guide_vertex))
                        : splitting ? Q * sizeof(st_guide_slot) : 0);
}

struct GuideCache {
  st_guide_header header{};
  std::vector<st_guide_region> regions;
  std::vector<st_guide_node> nodes;   // the cells' kd-trees (kernels/guiding.h): the cells first
  std::vector<int> node_depth;        // each node's depth below its cell (host only)
  std::vector<float> pixel_estimate;  // per film pixel: the training passes' mean over samples and RGB
  // host only: the fit weighs each guided vertex by what its direction brought back over the whole
  // rest of its path (its radiance record joined with the path's end) instead of the ring's last
  // bounces (guide_full_path_setting)
  bool full_path = false;
  // host only: the selection probability of every fitted region, or negative: learned from the
  // records where the mixture alone is sampled (guide_alpha_setting)
  float fixed_alpha = -1.0f;
  // host only: the last training pass's radiance records outside the grid, which the cells' trees
  // bin by clamping into the nearest cell (refine_guide_regions counts them; scatter vertices in a
  // medium lie inside it, and ground vertices make no records, so 0 unless something is wrong)
  size_t records_outside = 0;
  size_t bytes() const {
    return sizeof(st_guide_header) + regions.size() * sizeof(st_guide_region) + nodes.size() * sizeof(st_guide_node) +
           pixel_estimate.size() * sizeof(float);
  }
  // The device buffer's bytes for this cache grown to kGuideMaxRegions regions.
  size_t capacity_bytes() const;
  // The device buffer's contents: the header (its region and node counts set), the regions, the
  // nodes, then the pixel estimates.
  std::vector<unsigned char> serialize() const;
};

// An empty cache (every alpha 0, guided sampling, training and splitting off, pixel estimates 0)
// over the media and the film of `st`.
GuideCache make_guide_cache(const st_scene& st, int cells_longest_axis = kGuideGridCells);

// The pixel estimates from the training passes' sums of pixel means times spp over `samples`
// samples: each pixel's mean, raised to kGuidePixelFloor times the film's mean.
void set_pixel_estimates(GuideCache& cache, const std::vector<double>& sums, double samples);

// The region that holds world position (x, y, z) (the device's guide_region_index).
int guide_region_of(const GuideCache& cache, float x, float y, float z);

// Splits the regions that hold more than `split_above` radiance records of a training pass
// (`records`, any order): each at the median of its records' positions along the axis where they
// spread most, its halves again while they hold more, the most crowded region first (ties: the
// lower node index), until the cache holds `max_regions` regions or no region has more. Depends on
// the set of records only. Returns the regions added.
size_t refine_guide_regions(GuideCache& cache, const std::vector<st_guide_record>& records,
                            size_t split_above = kGuideSplitRecords, size_t max_regions = kGuideMaxRegions);

// Refits every region from `records` (any order; binned by position and put in key order here): its mixture from the records of the
// scatter events whose direction was guided (depth below kGuideDepth), its radiance (guided
// roulette's estimate) from the records of every depth; regions with fewer than kGuideMinRecords
// radiance records get no radiance estimate (records 0). Returns the regions that guide.
// Sparse regions (their fit records' effective count below kGuideMinRecords) take the fit of the
// smallest subtree of their cell, or block of cells, whose records' effective count reaches it.
// Each fitted region's alpha is learned from its records (GuideCache::fixed_alpha), which the
// training drew from the phase function or, where `sampled_by` (the cache that guided the pass)
// guided, its one-sample mixture.
int fit_guide_cache(GuideCache& cache, const std::vector<st_guide_record>& records,
                    const GuideCache* sampled_by = nullptr);

// The fixed selection probability of a render's fitted regions (GuideCache::fixed_alpha):
// SPECTRACK_GUIDE_ALPHA=A (0 <= A <= 0.9), for measurements; else -1 (learned).
float guide_alpha_setting();

// Prints to stderr what the fitted cache does to a path (guide_report.cpp): the mean second moment
// of the guided weight f_phase / p_mix per event over the guided regions, for a Henyey-Greenstein
// phase function of asymmetry hg, and the lobes of the most crowded regions with their cosine to
// the unit direction `sun` (none: 0). For measurements (SPECTRACK_GUIDE_REPORT=1).
void report_guide_cache(const GuideCache& cache, float hg, bool product, const float* sun, int pass);

}  // namespace spectrack
