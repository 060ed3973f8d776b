/*
 * The fake Arduino Due leg board: the firmware's own sketch (firmware/due/stride_link_due),
 * compiled for the host against the Arduino stubs (firmware/host-stubs), with the plant
 * (due_plant.c) behind the stub pins. The harness (drivers/fakes/src/due.rs) loads one copy of
 * this library per board, so each board has its own RAM, and calls the functions below: it
 * powers the board up (setup()), feeds it what the host sends, runs the clock forwards
 * (loop() again and again), takes what the sketch wrote to its serial port, and reads the
 * joints. Only these are exported.
 */
#include "due_plant.h"
#include "host_board.h"

#include "stride_link_due.ino"

#define DUE_BOARD_API extern "C" __attribute__((visibility("default")))

/* The plant's time step, µs. */
static const uint64_t STEP_US = 1000;

/* Whether this copy has been powered up already: a copy is for one board. */
static bool powered = false;

/* Powers the board up: the plant at rest, the sketch's setup(). Returns 0, or -1 when this copy
 * was powered up before (the loader handed out a used copy). */
DUE_BOARD_API int due_board_power_up(const due_plant_config *cfg) {
    if (powered) {
        return -1;
    }
    powered = true;
    host_board_reset();
    due_plant_init(cfg);
    setup();
    return 0;
}

/* Runs the clock dt_us forwards, the plant in steps of at most STEP_US. */
DUE_BOARD_API void due_board_advance(uint64_t dt_us) {
    uint64_t t = host_board_time_us();
    const uint64_t end = t + dt_us;
    while (t < end) {
        uint64_t step = end - t < STEP_US ? end - t : STEP_US;
        due_plant_step((double)step / 1e6);
        t += step;
        host_board_set_time_us(t);
    }
}

/* One turn of the sketch's loop(), which sees the time that passed since its last turn. The
 * harness turns it about every millisecond, or after it has written out what the board sent,
 * which at the line's pace takes the wire time: so, as on a board whose Serial.write blocks, a
 * sketch that sends more than the line carries sends less often, rather than build a queue. */
DUE_BOARD_API void due_board_loop(void) { loop(); }

/* Bytes from the host, into the serial port's buffer. */
DUE_BOARD_API void due_board_receive(const uint8_t *bytes, size_t n) {
    /* What does not fit in the port's buffer waits for the sketch to read some. */
    for (size_t at = host_serial_feed(bytes, n); at < n; at += host_serial_feed(bytes + at, n - at)) {
        loop();
    }
}

/* What the sketch wrote to its serial port, at most cap bytes. */
DUE_BOARD_API size_t due_board_take(uint8_t *out, size_t cap) { return host_serial_take(out, cap); }

/* The plant: its joints, its levers, what the joints do (see due_plant.h). */
DUE_BOARD_API int due_board_joints(void) { return DUE_PLANT_JOINTS; }

DUE_BOARD_API void due_board_set_extra_current(int joint, double ma) {
    due_plant_set_extra_current(joint, ma);
}

DUE_BOARD_API void due_board_set_tilt(double roll, double pitch) { due_plant_set_tilt(roll, pitch); }

DUE_BOARD_API int due_board_duty(int joint) { return due_plant_duty(joint); }

DUE_BOARD_API int due_board_braked(int joint) { return due_plant_braked(joint); }

DUE_BOARD_API double due_board_position(int joint) { return due_plant_position(joint); }

DUE_BOARD_API uint64_t due_board_pwm_changes(int joint) { return due_plant_pwm_changes(joint); }
