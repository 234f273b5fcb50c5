/* The wire protocol of descatter-labsim's simulated GPIO chip (a UNIX stream socket), shared by
 * the chip (drivers/labsim/gpio_chip_server.c) and the line backend that talks to it
 * (gpio_lines_socket.c). It exists because a line request must cross processes: descatterd's
 * trigger pulses a line that labsim's camera, another process, sees on its Line0 input; and
 * there is no kernel gpio-sim on the build machines.
 *
 * One connection is one line request, as a kernel line-request fd is: the lines are held while
 * the connection is open and released when it closes (however the client dies). Text lines of
 * ASCII ending in '\n', at most DS_GPIO_WIRE_MAX_LINE bytes with the '\n'; one reply per request:
 *
 *   request CONSUMER OFF[,OFF...] VAL[,VAL...]   -> ok N_CHIP_LINES      (once per connection)
 *   set VAL[,VAL...]                             -> ok                   (all lines at once)
 *   get                                          -> ok VAL[,VAL...]
 *   info                                         -> ok lines=N label=LABEL
 *
 * VAL is 0 or 1, one per requested offset, in request order; CONSUMER has no spaces. Failures
 * are "err CODE MESSAGE" and leave the connection usable, except a line longer than the limit,
 * after which the chip closes it. CODE is one of DS_GPIO_WIRE_ERR_*: busy (a line is held by
 * another connection: the kernel's EBUSY), range (an offset beyond the chip: the kernel's
 * EINVAL on a line it lacks), invalid (malformed), state (set/get before request, or a second
 * request). */
#pragma once

#define DS_GPIO_WIRE_MAX_LINE 512
#define DS_GPIO_WIRE_ERR_BUSY "busy"
#define DS_GPIO_WIRE_ERR_RANGE "range"
#define DS_GPIO_WIRE_ERR_INVALID "invalid"
#define DS_GPIO_WIRE_ERR_STATE "state"
/* The prefix of a daemon configuration's chip that names such a chip: "labsim:/run/x/gpio.sock". */
#define DS_GPIO_WIRE_CHIP_PREFIX "labsim:"
