/*
 * The Arduino core functions the sketch calls (Arduino.h, Wire.h), on the host: a clock the
 * harness sets, a serial port whose far end is two byte buffers, pins whose states the harness
 * reads, analog inputs and an I2C bus that ask the harness's world. See host_board.h.
 */
#include "Arduino.h"
#include "Wire.h"
#include "host_board.h"

#include <string.h>

HardwareSerialStub Serial;
TwoWireStub Wire;

namespace {

const size_t RX_CAP = 4096;
const size_t TX_CAP = 16384;
const size_t WIRE_CAP = 32; /* the Wire library's buffer */

struct Board {
    uint64_t t_us;
    int mode[HOST_BOARD_PINS];
    int level[HOST_BOARD_PINS];
    double duty[HOST_BOARD_PINS];
    /* Per pin: the last analogWrite value and how many times a write changed it. */
    uint32_t pwm_value[HOST_BOARD_PINS];
    uint64_t pwm_changes[HOST_BOARD_PINS];
    int write_bits, read_bits;
    bool serial_open;
    uint8_t rx[RX_CAP];
    size_t rx_at, rx_n;
    uint8_t tx[TX_CAP];
    size_t tx_n;
    bool wire_open;
    uint8_t wire_address;
    uint8_t wire_tx[WIRE_CAP];
    size_t wire_tx_n;
    uint8_t wire_rx[WIRE_CAP];
    size_t wire_rx_at, wire_rx_n;
};

Board board;

bool valid(uint32_t pin) { return pin < HOST_BOARD_PINS; }

} // namespace

extern "C" void host_board_reset(void) {
    memset(&board, 0, sizeof board);
    for (int p = 0; p < HOST_BOARD_PINS; p++) {
        board.mode[p] = -1;
    }
    board.write_bits = 8;
    board.read_bits = 10;
}

extern "C" void host_board_set_time_us(uint64_t t_us) { board.t_us = t_us; }

extern "C" uint64_t host_board_time_us(void) { return board.t_us; }

extern "C" size_t host_serial_feed(const uint8_t *bytes, size_t n) {
    if (!board.serial_open) {
        return n; /* a closed port: the bytes are lost */
    }
    if (board.rx_at > 0) {
        memmove(board.rx, board.rx + board.rx_at, board.rx_n);
        board.rx_at = 0;
    }
    size_t room = RX_CAP - board.rx_n;
    size_t k = n < room ? n : room;
    memcpy(board.rx + board.rx_n, bytes, k);
    board.rx_n += k;
    return k;
}

extern "C" size_t host_serial_take(uint8_t *out, size_t cap) {
    size_t k = board.tx_n < cap ? board.tx_n : cap;
    memcpy(out, board.tx, k);
    memmove(board.tx, board.tx + k, board.tx_n - k);
    board.tx_n -= k;
    return k;
}

extern "C" int host_pin_mode(uint8_t pin) { return valid(pin) ? board.mode[pin] : -1; }

extern "C" int host_pin_level(uint8_t pin) {
    return valid(pin) && board.mode[pin] == OUTPUT ? board.level[pin] : 0;
}

extern "C" double host_pin_duty(uint8_t pin) { return valid(pin) ? board.duty[pin] : 0; }

extern "C" uint64_t host_pin_pwm_changes(uint8_t pin) { return valid(pin) ? board.pwm_changes[pin] : 0; }

void pinMode(uint8_t pin, uint8_t mode) {
    if (valid(pin)) {
        board.mode[pin] = mode;
    }
}

void digitalWrite(uint8_t pin, uint8_t value) {
    if (valid(pin)) {
        board.level[pin] = value ? HIGH : LOW;
        board.duty[pin] = value ? 1.0 : 0.0;
    }
}

void analogWrite(uint32_t pin, uint32_t value) {
    /* As on the Due: the pin becomes a PWM output; the value is read at the write resolution. */
    if (valid(pin)) {
        double full = (double)((1UL << board.write_bits) - 1);
        board.mode[pin] = OUTPUT;
        if (value != board.pwm_value[pin]) {
            board.pwm_changes[pin]++;
            board.pwm_value[pin] = value;
        }
        board.duty[pin] = value >= full ? 1.0 : value / full;
        board.level[pin] = value > 0;
    }
}

int analogRead(uint8_t pin) {
    if (pin < A0) {
        pin += A0; /* as on the Due: a channel number */
    }
    double full = (double)((1UL << board.read_bits) - 1);
    double v = host_world_analog_volts(pin) / HOST_BOARD_VREF * full;
    if (v < 0) {
        v = 0;
    }
    if (v > full) {
        v = full;
    }
    return (int)(v + 0.5);
}

void analogWriteResolution(int bits) {
    if (bits >= 1 && bits <= 16) {
        board.write_bits = bits;
    }
}

void analogReadResolution(int bits) {
    if (bits >= 1 && bits <= 16) {
        board.read_bits = bits;
    }
}

uint32_t millis(void) { return (uint32_t)(board.t_us / 1000); }

uint32_t micros(void) { return (uint32_t)board.t_us; }

void HardwareSerialStub::begin(unsigned long) {
    board.serial_open = true;
    board.rx_at = board.rx_n = 0;
}

int HardwareSerialStub::available(void) { return (int)board.rx_n; }

int HardwareSerialStub::read(void) {
    if (board.rx_n == 0) {
        return -1;
    }
    board.rx_n--;
    return board.rx[board.rx_at++];
}

size_t HardwareSerialStub::write(const uint8_t *buf, size_t n) {
    if (!board.serial_open) {
        return 0;
    }
    size_t room = TX_CAP - board.tx_n;
    size_t k = n < room ? n : room;
    memcpy(board.tx + board.tx_n, buf, k);
    board.tx_n += k;
    return k;
}

void TwoWireStub::begin(void) { board.wire_open = true; }

void TwoWireStub::beginTransmission(uint8_t address) {
    board.wire_address = address;
    board.wire_tx_n = 0;
}

size_t TwoWireStub::write(uint8_t byte) {
    if (board.wire_tx_n == WIRE_CAP) {
        return 0;
    }
    board.wire_tx[board.wire_tx_n++] = byte;
    return 1;
}

uint8_t TwoWireStub::endTransmission(bool) {
    /* Arduino's codes: 0 done, 2 no acknowledgement of the address, 4 another error. */
    if (!board.wire_open) {
        return 4;
    }
    return host_world_i2c_write(board.wire_address, board.wire_tx, board.wire_tx_n) == 0 ? 0 : 2;
}

uint8_t TwoWireStub::requestFrom(uint8_t address, uint8_t count) {
    board.wire_rx_at = board.wire_rx_n = 0;
    if (!board.wire_open) {
        return 0;
    }
    size_t n = count < WIRE_CAP ? count : WIRE_CAP;
    board.wire_rx_n = host_world_i2c_read(address, board.wire_rx, n);
    return (uint8_t)board.wire_rx_n;
}

int TwoWireStub::available(void) { return (int)(board.wire_rx_n - board.wire_rx_at); }

int TwoWireStub::read(void) {
    if (board.wire_rx_at == board.wire_rx_n) {
        return -1;
    }
    return board.wire_rx[board.wire_rx_at++];
}
