"""`snakebot foxglove-layout`: write the Foxglove layout for the live topics."""

from __future__ import annotations

import json
from pathlib import Path

import click

from snakebot.cli.options import json_option, output_option
from snakebot.cli.output import dumps
from snakebot.formats.live_topics import layout_text
from snakebot.userfiles import write_atomic


@click.command("foxglove-layout")
@output_option("The layout file to write (import it in Foxglove: Layouts, Import from file)")
@json_option()
def foxglove_layout(output: Path, as_json: bool) -> None:
    """Write the Foxglove layout for the robot live (--foxglove) and its recordings (--mcap).

    The layout shows the robot in a 3-D panel (its URDF from /robot_description,
    following its body on /tf, and /scene), plots of the joints' angles and goals, and
    the controller's state over time.

    \b
        snakebot foxglove-layout -o snakebot-layout.json
        snakebot sim serve --foxglove 8765    # then in Foxglove: ws://127.0.0.1:8765
    """
    text = layout_text()
    written = write_atomic(output, text)
    panels = sorted(json.loads(text)["configById"])
    if as_json:
        click.echo(dumps({"layout": str(written), "panels": panels}))
    else:
        click.echo(f"wrote {written}: a Foxglove layout with {', '.join(panels)}")
