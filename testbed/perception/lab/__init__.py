"""Lane-detector lab drives: closed-loop accuracy per condition, drives in traffic."""
