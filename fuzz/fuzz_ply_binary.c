/* libFuzzer target: bsurf_read_buffer as a PLY file, seeded with binary
 * little- and big-endian PLY (corpus/fuzz_ply_binary, dictionary ply.dict).
 * The reader is the same as fuzz_ply_ascii's; the corpus keeps each run on
 * one encoding's code. */
#define FUZZ_FORMAT BSURF_FORMAT_PLY
#include "fuzz_reader.h"
