/* magcal-replay --stream: every row, in file order, through the continuous calibrator
 * (include/magcal/continuous.h) exactly as firmware calls it: push per row, step per row at the
 * default budget, heading per row. docs/replay.md, docs/calibrator.md "Continuous calibrator". */
#ifndef REPLAY_STREAM_H
#define REPLAY_STREAM_H

/** 1 when argv holds --stream (the stream mode then owns the command line). */
int replay_stream_requested(int argc, char **argv);

/** The stream mode's main: exit status as magcal-replay's (0 ok, 1 usage, 2 input, 3 no
 *  calibration at the end, 4 output error). */
int replay_stream_main(int argc, char **argv);

#endif
