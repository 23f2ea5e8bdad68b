/* fake_khepera4.h: the simulated robot's own calls (not libkhepera's): its time. */
#ifndef FAKE_KHEPERA4_H
#define FAKE_KHEPERA4_H

/* The simulated robot's time (s). */
double fake_khepera_time(void);
/* Runs the simulated robot until `until` (s), 1 ms at a time. */
void fake_khepera_advance(double until);

#endif
