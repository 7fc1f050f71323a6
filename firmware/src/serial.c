/* USART0 at 115200 8N1 (U2X, UBRR 16: 117647 baud, +2.1 %, as every Arduino at 16 MHz) with 256-byte rings.
 *
 * The receive interrupt also follows the line framing (protocol.c's, byte for byte) to restart the watchdog the
 * moment a request line is complete: at its "\n", or at its 96th byte when it is too long (ERR 5). */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include "protocol_table.h"
#include "serial.h"
#include "sphere.h"

static volatile uint8_t rx_buf[256];
static volatile uint8_t rx_head, rx_tail;       /* uint8_t indexes wrap at 256 by themselves */
static volatile uint8_t tx_buf[256];
static volatile uint8_t tx_head, tx_tail;
static uint8_t line_len, discarding;            /* the receive interrupt's view of the line framing */

void serial_init(void)
{
    UBRR0 = 16;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);         /* 8N1 */
    UCSR0B = _BV(RXCIE0) | _BV(RXEN0) | _BV(TXEN0);
}

ISR(USART0_RX_vect)
{
    uint8_t c = UDR0;
    if ((uint8_t)(rx_head + 1) != rx_tail)
        rx_buf[rx_head++] = c;                  /* full: the byte is lost (the line it belongs to gets an ERR) */
    if (c == '\n') {
        if (!discarding)
            sphere_request_seen();
        discarding = 0;
        line_len = 0;
    } else if (!discarding && ++line_len >= PROTO_MAX_REQUEST_BYTES) {
        sphere_request_seen();                  /* a line too long counts as a request (ERR 5) */
        discarding = 1;
        line_len = 0;
    }
}

ISR(USART0_UDRE_vect)
{
    if (tx_head != tx_tail)
        UDR0 = tx_buf[tx_tail++];
    else
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
}

uint8_t serial_available(void)
{
    return rx_head != rx_tail;
}

uint8_t serial_read(void)
{
    return rx_buf[rx_tail++];
}

void serial_write(const char *data, uint8_t n)
{
    for (uint8_t i = 0; i < n; i++) {
        while ((uint8_t)(tx_head + 1) == tx_tail) {
            wdt_reset();                        /* the ring drains at 11.8 bytes per ms */
            sleep_mode();
        }
        tx_buf[tx_head++] = (uint8_t)data[i];
        UCSR0B |= _BV(UDRIE0);
    }
}
