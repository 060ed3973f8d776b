/* The public liblcm API: lcm.h pulls in eventlog.h. */
#include <lcm/lcm.h>
#include <lcm/eventlog.h>
