// film_watch.h: looking at a film while it renders: a noise target that stops the render, a
// progressive preview, checkpoints, and the resumption of a render from a checkpoint.
//
// Design: a FilmWatch is the renderer's one hook into its stage loop (RenderOptions::watch). After
// every iteration that added batches to the film, the loop asks wants() what to read; it then reads
// the film (the same read as at the end, so the partial result is exactly a render of the samples
// done so far) and, when asked, the device film itself (FilmState: every layer's compensated float
// sums and their compensation terms, bit for bit), and passes them to see(), which may stop the
// render (a noise target met). Films sum one sample at a time in sample order (k_accumulate), so a
// film state of the first k samples, loaded back before samples k .. spp - 1 are rendered, gives the
// uninterrupted render's sums to the bit: resume() hands such a state to the loop. Guiding's
// training passes are not watched; a render whose film holds their samples shows the watch its film
// with them, and wants(), samples_needed() and the film's spp_done count them (the image's samples);
// a FilmState holds the stage loop's own film and samples (checkpoints refuse guiding).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "film/film.h"
#include "integrator/renderer.h"

namespace spectrack {

// The device film of a render: samples sample_begin .. sample_begin + samples_done - 1 of npix
// pixels, `layers` float4 layers of sums and compensation terms (kernels/finish.cl's layout: per
// layer, npix float4 of sums then npix of compensations).
struct FilmState {
  int64_t sample_begin = 0, samples_done = 0;
  uint64_t npix = 0, layers = 0;
  std::vector<float> film;  // 2 * layers * npix * 4 floats
};

class FilmWatch {
 public:
  virtual ~FilmWatch() = default;
  enum Want : int { kNothing = 0, kFilm = 1, kState = 2 };
  // After batches were added (samples_done of the range so far, resumed samples included): what to
  // read now, kNothing, kFilm or kFilm | kState.
  virtual int wants(int64_t samples_done) = 0;
  // The film so far (and the device film when asked); true stops the render: the result then
  // holds these samples and RenderResult::noise_target_reached is set.
  virtual bool see(const RenderResult& film, const FilmState* state) = 0;
  // The samples (of the range, resumed ones and a guided render's training samples included) that
  // may be issued before the next look: a noise target's next check, so that paths past it are not
  // started and dropped.
  virtual int64_t samples_needed() const { return INT64_MAX; }
  // At the end of the stage loop (finished, stopped or interrupted), when wants_final_state(): the
  // device film as it ends.
  virtual bool wants_final_state() const { return false; }
  virtual void final_state(const FilmState& state) { (void)state; }
  // A film to continue from (nullptr: start from zero). The loop renders the samples after it.
  virtual const FilmState* resume() const { return nullptr; }
};

// A film state on disk ("spectrack-film-state/2": a text header naming the render and holding the
// SHA-1 of the state, then the floats): `key` names the render it belongs to (identity and sample
// range; film_state_key), and reading refuses anything but a regular file, a file of another
// render, a truncated, malformed or damaged one (the digest differs, a value is not finite),
// naming the file.
std::string film_state_key(const RenderIdentity& id, const FilmWindow& window, int64_t sample_begin, int spp);
void write_film_state(const std::string& path, const FilmState& state, const std::string& key);
FilmState read_film_state(const std::string& path, const std::string& key);

}  // namespace spectrack
