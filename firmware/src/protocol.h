/* The request interpreter: docs/led-sphere-protocol.md, with the table of drivers/led_sphere/protocol.py
 * (protocol_table.h, generated). */
#ifndef PROTOCOL_H
#define PROTOCOL_H

#include <stdint.h>

/* The serial number IDN? reports (printable ASCII, no spaces; read from the EEPROM at start). */
void protocol_init(const char *serial);

/* Take the bytes received so far; answers every complete request line. Returns 1 while a request waits for the
 * LED current sense to settle (FAULT?, STATUS?: at most SENSE_SETTLE_MS), 0 when idle. */
uint8_t protocol_poll(void);

#endif
