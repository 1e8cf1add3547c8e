from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_liveview'

setup(
    name=package_name,
    version='0.9.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'The live view: a Foxglove WebSocket server of a run, and the frame tree publisher.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'frames = activesurv_liveview.frames_node:main',
            'live_view = activesurv_liveview.live_view_node:main',
        ],
    },
)
