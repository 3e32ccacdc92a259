"""The bottom of the flexarm stack: the robot's shared facts and basics (pure), and the helpers
every node uses. Every other flexarm package may import it; it imports none of them."""
