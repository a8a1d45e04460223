"""ament_python build description of rheo_shaping (colcon build / pip install)."""
from glob import glob

from setuptools import find_packages
from setuptools import setup

package_name = 'rheo_shaping'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test*']),
    package_data={package_name: ['data/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', sorted(glob('config/*.yaml'))),
        ('share/' + package_name + '/launch', sorted(glob('launch/*.launch.py'))),
        ('share/' + package_name + '/rviz', sorted(glob('rviz/*.rviz'))),
    ],
    python_requires='>=3.10',
    install_requires=['setuptools'],
    # colcon test runs pytest (not unittest) when pytest is a test dependency
    tests_require=['pytest'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='rheo_shaping developers',
    maintainer_email='dev@rheo-shaping.invalid',
    keywords=['ROS'],
    classifiers=[
        'Intended Audience :: Developers',
        'License :: OSI Approved :: Apache Software License',
        'Programming Language :: Python',
        'Topic :: Scientific/Engineering',
    ],
    description='Robotic shaping of thin rheological sheets over a mould (ROS 2 Jazzy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'simulator = rheo_shaping.nodes.entry:simulator',
            'planner = rheo_shaping.nodes.entry:planner',
            'monitor = rheo_shaping.nodes.entry:monitor',
            'rheo-shaping = rheo_shaping.cli:main',
        ],
    },
)
