"""Protocol-faithful test servers (stdlib only) that clients are tested against on 127.0.0.1."""
