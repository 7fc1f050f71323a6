/* The simulated chip's USB cable: a pseudo-terminal the host opens as its serial port (pyserial, the driver),
 * bridged to the ATmega2560's USART0, with the cable's faults (wire faults) applied line by line. */
#ifndef BRIDGE_H
#define BRIDGE_H

#include <stdint.h>

/* What happens to a request line and its reply (set by the harness's "wire" command). */
enum wire_fault {
    WIRE_NO_REPLY = 1,      /* the request reaches the chip, its reply is lost */
    WIRE_HANG = 2,          /* the request never reaches the chip (and so has no reply) */
    WIRE_GARBLED = 4,       /* the reply's bytes are corrupted */
    WIRE_SLOW = 8,          /* the reply arrives delay_ms later (wall clock) */
};

typedef struct bridge bridge_t;

/* Callbacks into the harness: a byte for the chip's receiver (returns 0 while it has no room: try later), and
 * events for the pin log ('H' the host closed the port or vanished, 'C' a host opened it). */
typedef int (*bridge_to_chip_fn)(void *ctx, uint8_t byte);
typedef void (*bridge_event_fn)(void *ctx, char kind);

bridge_t *bridge_open(bridge_to_chip_fn to_chip, bridge_event_fn event, void *ctx);
const char *bridge_port(const bridge_t *b);
int bridge_fd(const bridge_t *b);               /* for poll(); -1 once unplugged */
int bridge_wants_poll(const bridge_t *b);       /* a host holds the port (poll the fd for input) */

void bridge_service(bridge_t *b, uint64_t wall_ns); /* read the host, feed the chip, send due replies */
void bridge_from_chip(bridge_t *b, uint8_t byte, uint64_t wall_ns);  /* a byte the chip transmitted */
void bridge_unplug(bridge_t *b);                /* the cable pulled: the port disappears */

/* Start ``fault`` for requests whose keyword is one of ``keywords`` (space-separated, upper case; "" for every
 * request), as the emulator's inject(fault, keywords=...) does; returns -1 for keywords too long to hold. */
int bridge_set_fault(bridge_t *b, enum wire_fault fault, uint32_t delay_ms, const char *keywords);
void bridge_clear_faults(bridge_t *b);

#endif
