from peppygen import NodeBuilder

from py_joint_follower import setup


def main() -> None:
    NodeBuilder().run(setup)


if __name__ == "__main__":
    main()
