// renderer_watch.cpp: the stage loop's watch (integrator/film_watch.h): reading the device film
// exactly (a FilmState) and loading one back for a resumed render, a look at the film after new
// batches, and the batches the loop may issue before the watch looks again.
#include <fmt/format.h>

#include <optional>

#include "integrator/film_watch.h"
#include "integrator/renderer_impl.h"

namespace spectrack {

FilmState Renderer::Impl::film_state(const RenderBuffers& b, const BatchPlan& p, const LoopState& s, int64_t sample_begin) {
  FilmState st;
  st.sample_begin = sample_begin;
  st.samples_done = int64_t(s.samples_before + s.samples_done);
  st.npix = p.npix;
  st.layers = p.film_layers();
  st.film.resize(2 * st.layers * st.npix * 4);
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.film, CL_TRUE, 0, st.film.size() * sizeof(float), st.film.data()),
              "read the film state");
  return st;
}

void Renderer::Impl::load_film_state(const RenderBuffers& b, const BatchPlan& p, const FilmState& st) {
  if (st.npix != p.npix || st.layers != p.film_layers() || st.film.size() != 2 * p.film_layers() * p.npix * 4)
    throw Error(fmt::format("internal: a film state of {} pixels and {} layers resumed in a film of {} and {}", st.npix,
                            st.layers, p.npix, p.film_layers()));
  ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b.film, CL_TRUE, 0, st.film.size() * sizeof(float), st.film.data()),
              "load the resumed film");
}

// The guide's training samples on the film the watch sees (0 without them): the watch counts the
// samples of the image, the stage loop its own (docs/guiding.md, "Determinism across shards").
int64_t Renderer::Impl::watched_training_samples() const {
  return watch_with_training ? guide_samples.spp_done : 0;
}

// The batches that hold the samples the watch needs before its next look (at least one more than
// are on the film, so the loop never waits on a watch that will not look).
void Renderer::Impl::limit_issue(LoopState& s, const BatchPlan& p, const FilmWatch& w) {
  const int64_t needed = w.samples_needed() - int64_t(s.samples_before) - watched_training_samples();
  if (needed >= int64_t(p.spp)) {
    s.batches_issuable = UINT64_MAX;
    return;
  }
  const uint64_t batches = needed <= 0 ? 0 : (uint64_t(needed) + p.samples_per_batch - 1) / p.samples_per_batch;
  s.batches_issuable = std::max<uint64_t>(batches, s.accumulated + 1);
}

// After new batches: the film (and its state) when the watch asks; true stops the loop (the
// batches on the film are the result, the paths in flight are dropped).
bool Renderer::Impl::watch_film(const RenderBuffers& b, const BatchPlan& p, LoopState& s, const RenderResult& header) {
  const int want = opt.watch->wants(int64_t(s.samples_before + s.samples_done) + watched_training_samples());
  if (!(want & FilmWatch::kFilm)) return false;
  RenderResult film = result_header(header.sample_begin, header.spp_requested);
  read_film(b, p, s, film);
  if (watch_with_training) add_guide_samples(film);  // the film the render returns holds them
  film.interrupted = false;  // a look at a render in progress
  std::optional<FilmState> st;
  if (want & FilmWatch::kState) st = film_state(b, p, s, header.sample_begin);
  const bool stop = opt.watch->see(film, st ? &*st : nullptr);
  limit_issue(s, p, *opt.watch);
  if (!stop) return false;
  s.noise_target_reached = true;
  return true;
}

}  // namespace spectrack
