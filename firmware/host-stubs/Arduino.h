/* Just enough of the Arduino core's declarations to compile the sketch on the host: as a syntax
 * and type check (scripts/firmware) when no Arduino toolchain is installed, and to run it as the
 * fake board of the tests with host_board.cpp behind them (see host_board.h). */
#ifndef ARDUINO_H_HOST_STUB
#define ARDUINO_H_HOST_STUB
#include <stdint.h>
#include <stdlib.h>
#include <stddef.h>

#define HIGH 1
#define LOW 0
#define OUTPUT 1
#define INPUT 0
#define A0 54
#define A1 55
#define A2 56
#define A3 57
#define A4 58
#define A5 59

void pinMode(uint8_t pin, uint8_t mode);
void digitalWrite(uint8_t pin, uint8_t value);
void analogWrite(uint32_t pin, uint32_t value);
int analogRead(uint8_t pin);
void analogWriteResolution(int bits);
void analogReadResolution(int bits);
uint32_t millis(void);
uint32_t micros(void);

class HardwareSerialStub {
  public:
    void begin(unsigned long baud);
    int available(void);
    int read(void);
    size_t write(const uint8_t *buf, size_t n);
};
extern HardwareSerialStub Serial;
#endif
