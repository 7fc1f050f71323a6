/* USART0 (the Mega's USB serial, /dev/ttyACM0): 115200 8N1, interrupt-driven ring buffers. */
#ifndef SERIAL_H
#define SERIAL_H

#include <stdint.h>

void serial_init(void);
uint8_t serial_available(void);
uint8_t serial_read(void);              /* call only when serial_available() */
void serial_write(const char *data, uint8_t n);  /* waits for room (the transmit interrupt drains it) */

#endif
