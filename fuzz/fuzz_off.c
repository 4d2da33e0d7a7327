/* libFuzzer target: bsurf_read_buffer as an OFF file (OFF, NOFF, COFF,
 * NCOFF, STOFF; corpus/fuzz_off, dictionary off.dict). */
#define FUZZ_FORMAT BSURF_FORMAT_OFF
#include "fuzz_reader.h"
