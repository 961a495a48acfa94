// merge_files.h: `spectrack merge` of film-piece files in bounded memory.
//
// Design: the headers of the inputs are read first (read_merge_headers) and the merge is planned
// and checked on them alone (plan_merge: one render, no overlap, no gap, the same samples on
// every pixel). The pixels then go through one band of output rows at a time: for each band,
// each input that covers it (in the order given) is opened, its rows of the band read and turned
// back into sums (PieceDecoder), and added into the band's sums, which are written out
// (piece_exr_channels, piece_beauty) before the next band. Per pixel these are the operations of
// read_piece, merge_pieces and write_piece in the same order, so the image is the same, bit for
// bit, as a merge of whole images. Memory: one band (kMergeBandBytes, or one row where a row is
// larger) plus one open input, whatever the number and size of the inputs; the headers (a few
// hundred bytes each) are all held.
#pragma once
#include <string>
#include <vector>

#include "image/image.h"
#include "film/film.h"

namespace spectrack {

// What a band of rows may take: sums, an input's rows and the output rows together.
constexpr size_t kMergeBandBytes = size_t(32) << 20;

// One input's header: the piece (source: the path; no sums), its layer channels and metadata.
struct MergeInput {
  FilmPiece piece;
  std::vector<std::string> extra_names;
  Metadata meta;
};
MergeInput read_merge_header(const std::string& path);

// Writes the merge of `inputs` (laid out by layout = plan_merge of their pieces) to `output`, an
// EXR, and to `preview`, a PNG, when not empty, with `meta` besides the piece's metadata. Each file
// appears whole or not at all (image_rows.h); throws Error naming the input at fault.
void write_merged(const std::vector<MergeInput>& inputs, const FilmPiece& layout, const std::string& output,
                  const std::string& preview, const Metadata& meta, const ExrOptions& exr,
                  size_t band_bytes = kMergeBandBytes);

}  // namespace spectrack
