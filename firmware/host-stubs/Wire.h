/* The Wire (I2C) interface the sketch uses: for the host syntax check, and run on the host by
 * host_board.cpp against the devices the harness puts on the bus (see host_board.h). */
#ifndef WIRE_H_HOST_STUB
#define WIRE_H_HOST_STUB
#include <stdint.h>
#include <stddef.h>

class TwoWireStub {
  public:
    void begin(void);
    void beginTransmission(uint8_t address);
    size_t write(uint8_t byte);
    uint8_t endTransmission(bool stop = true);
    uint8_t requestFrom(uint8_t address, uint8_t count);
    int available(void);
    int read(void);
};
extern TwoWireStub Wire;
#endif
