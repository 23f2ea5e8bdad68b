/* fake_clock.c: the robot programs' clock (khepera_clock.h) on the simulated robot's time: a
 * program's sleep runs the simulated robot until its deadline. Linked in place of the generated
 * khepera_clock.c in khepera_gym's tests. */
#include "fake_khepera4.h"
#include "khepera_clock.h"

double khepera_clock_now(void)
{
    return fake_khepera_time();
}

void khepera_clock_sleep_until(double deadline)
{
    fake_khepera_advance(deadline);
}
