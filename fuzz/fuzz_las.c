/* libFuzzer target: bsurf_read_buffer as LAS (corpus/fuzz_las). */
#define FUZZ_FORMAT BSURF_FORMAT_LAS
#include "fuzz_reader.h"
